"""The safety flight's figures: the hover's drift is measured on the true track and reported, never judged; after a link
fault the altitude limits are judged from the moment the body is back inside them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from feelium.lab.flight.plant_bench import _summary
from feelium.lab.flight.safety import GOALS, REPORTED, SafetyResult, back_inside_limits, farthest_along, farthest_from_start


def test_the_drift_is_the_farthest_point_from_where_the_track_began_not_from_its_middle_or_its_end() -> None:
    # out 0.3 m east, back through the start, 0.1 m west: the farthest point is 0.3 m away, the end 0.1 m
    x = np.array([0.0, 0.1, 0.3, 0.1, 0.0, -0.1])
    y = np.zeros_like(x)
    assert farthest_from_start(x, y) == 0.3
    assert math.isclose(farthest_from_start(np.array([1.0, 1.3]), np.array([2.0, 2.4])), 0.5)
    assert farthest_from_start(np.array([]), np.array([])) == 0.0


# the fault ends at 2 s with the body still inside but climbing; it peaks 0.4 m over the 2.6 m limit at 3 s (the fault's
# climb carried on), is back inside at 5 s, and goes out again by 0.15 m at 9 s: only that is judged; then the same under
# the 0.4 m floor limit
AFTER_A_FAULT = [([2.0, 2.3, 2.5, 3.0, 2.7, 2.6, 2.5, 2.6, 2.6, 2.75, 2.6, 2.5], 0.15),
                 ([1.0, 0.6, 0.45, 0.2, 0.3, 0.45, 0.5, 0.45, 0.45, 0.3, 0.45, 0.5], 0.1)]


@pytest.mark.parametrize("z,judged", AFTER_A_FAULT)
def test_after_a_fault_the_limits_are_judged_from_the_body_s_return_not_on_the_climb_the_fault_started(
        z: list[float], judged: float) -> None:
    returned, excursion = back_inside_limits(np.arange(12) * 1.0, np.array(z), 2.0, 0.4, 2.6, 0.0)
    assert returned == 3.0
    assert math.isclose(excursion, judged)


def test_a_climb_long_after_the_fault_is_judged_even_if_the_body_never_left_the_limits_in_the_aftermath() -> None:
    t = np.arange(12) * 1.0
    z = np.array([2.0, 2.3, 2.5, 2.55, 2.5, 2.5, 2.6, 2.6, 2.6, 2.9, 3.0, 2.7])
    returned, excursion = back_inside_limits(t, z, 2.0, 0.4, 2.6, 0.0)
    assert returned == 0.0
    assert math.isclose(excursion, 0.4)


def test_a_body_back_within_the_goal_s_tolerance_of_a_limit_is_back() -> None:
    t = np.arange(8) * 1.0
    # after the fault the body rests 4-6 cm over the limit: within the goal's 10 cm, it is back; the 0.12 m later is not
    z = np.array([2.5, 3.0, 2.8, 2.66, 2.64, 2.66, 2.72, 2.64])
    returned, excursion = back_inside_limits(t, z, 1.0, 0.4, 2.6, 0.1)
    assert returned == 2.0
    assert math.isclose(excursion, 0.12)


def test_a_body_that_never_comes_back_inside_the_limits_has_no_finite_figure_and_one_inside_all_along_none() -> None:
    t = np.arange(5) * 1.0
    assert back_inside_limits(t, np.full(5, 2.8), 1.0, 0.4, 2.6, 0.1) == (math.inf, math.inf)
    assert back_inside_limits(t, np.array([1.0, 1.2, 1.1, 1.3, 1.2]), 1.0, 0.4, 2.6, 0.1) == (0.0, 0.0)


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
