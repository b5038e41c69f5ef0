"""The safety flight's figures: the hover's drift is measured on the true track and reported, never judged."""

from __future__ import annotations

import math

import numpy as np

from feelium.lab.flight.plant_bench import _summary
from feelium.lab.flight.safety import GOALS, REPORTED, SafetyResult, farthest_from_start


def test_the_drift_is_the_farthest_point_from_where_the_track_began_not_from_its_middle_or_its_end() -> None:
    # out 0.3 m east, back through the start, 0.1 m west: the farthest point is 0.3 m away, the end 0.1 m
    x = np.array([0.0, 0.1, 0.3, 0.1, 0.0, -0.1])
    y = np.zeros_like(x)
    assert farthest_from_start(x, y) == 0.3
    assert math.isclose(farthest_from_start(np.array([1.0, 1.3]), np.array([2.0, 2.4])), 0.5)
    assert farthest_from_start(np.array([]), np.array([])) == 0.0


def test_a_reported_figure_is_in_the_figures_but_never_a_failure() -> None:
    result = SafetyResult("p", hover_drift_m=5.0)
    assert set(REPORTED).isdisjoint(GOALS)
    assert result.figures()["hover_drift_m"] == 5.0
    assert result.failures() == {}


def test_the_bench_summary_gives_a_reported_figure_its_median_and_worst_plant_without_a_goal() -> None:
    rows = [{"plant": name, "figures": {**{goal: 0.0 for goal in GOALS}, "hover_drift_m": drift}, "failures": {}}
            for name, drift in (("a", 0.1), ("b", 0.4), ("c", 0.2))]
    summary = _summary(rows)["hover_drift_m"]
    assert summary == {"goal": None, "median": 0.2, "worst": 0.4, "worst_plant": "b"}
