"""The safety flight's figures: the hover's drift is measured on the true track and reported, never judged."""

from __future__ import annotations

import math

import numpy as np

from feelium.lab.flight.plant_bench import _summary
from feelium.lab.flight.safety import GOALS, REPORTED, SafetyResult, farthest_along, farthest_from_start


def test_the_drift_is_the_farthest_point_from_where_the_track_began_not_from_its_middle_or_its_end() -> None:
    # out 0.3 m east, back through the start, 0.1 m west: the farthest point is 0.3 m away, the end 0.1 m
    x = np.array([0.0, 0.1, 0.3, 0.1, 0.0, -0.1])
    y = np.zeros_like(x)
    assert farthest_from_start(x, y) == 0.3
    assert math.isclose(farthest_from_start(np.array([1.0, 1.3]), np.array([2.0, 2.4])), 0.5)
    assert farthest_from_start(np.array([]), np.array([])) == 0.0


def test_the_surge_drift_counts_only_the_part_along_the_body_so_a_cross_draft_is_not_charged_to_the_surge_loop() -> None:
    # heading 90 deg: the body's axis is +y; 0.5 m east (sideways) and 0.2 m back along the axis
    x = np.array([0.0, 0.25, 0.5, 0.5])
    y = np.array([0.0, 0.0, 0.0, -0.2])
    assert math.isclose(farthest_along(x, y, 90.0), 0.2, abs_tol=1e-12)
    assert math.isclose(farthest_along(x, y, 0.0), 0.5, abs_tol=1e-12)
    assert math.isclose(farthest_from_start(x, y), math.hypot(0.5, 0.2))
    assert farthest_along(np.array([]), np.array([]), 0.0) == 0.0


def test_a_reported_figure_is_in_the_figures_but_never_a_failure() -> None:
    result = SafetyResult("p", hover_drift_m=5.0)
    assert set(REPORTED).isdisjoint(GOALS)
    assert result.figures()["hover_drift_m"] == 5.0
    assert result.failures() == {}


def test_the_bench_summary_gives_a_reported_figure_its_median_and_worst_plant_without_a_goal() -> None:
    rows = [{"plant": name, "figures": {**{goal: 0.0 for goal in GOALS}, "hover_drift_m": drift, "hover_surge_drift_m": 0.0},
             "failures": {}}
            for name, drift in (("a", 0.1), ("b", 0.4), ("c", 0.2))]
    summary = _summary(rows)["hover_drift_m"]
    assert summary == {"goal": None, "median": 0.2, "worst": 0.4, "worst_plant": "b"}
