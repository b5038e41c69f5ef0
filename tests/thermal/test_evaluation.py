"""Presence scoring on simulated clips: the scorer's bookkeeping and the detector's numbers on a small set."""

import numpy as np
import pytest

from feelium.sim.thermal import Visit
from feelium.thermal.config import PresenceConfig
from feelium.lab.thermal.evaluation import Clip, approach_clip, evaluate_presence, run_clip


def test_visit_near_interval_matches_its_distance():
    v = Visit(t_start=2.0, walk_s=4.0, stay_s=3.0, u=0.5, v=0.5, radius=0.1, far_mm=2000.0, near_mm=0.0)
    t_in, t_out = v.near_interval(500.0)
    assert v.distance(t_in) == pytest.approx(500.0) and v.distance(t_out) == pytest.approx(500.0)
    assert v.distance(1.0) is None and v.distance(v.t_end + 0.1) is None
    assert Visit(0, 1, 1, 0.5, 0.5, 0.1, near_mm=600.0).near_interval(500.0) is None


def test_approach_clips_are_seeded():
    a = approach_clip(np.random.default_rng(4), 0)
    b = approach_clip(np.random.default_rng(4), 0)
    assert a == b and a.duration_s > a.visits[0].t_end


def test_a_hot_enough_detector_misses_everything():
    # a detector that needs 30 degC of rise can never fire: the scorer must report misses, not invent hits
    report = evaluate_presence(approach=3, empty=1, empty_s=30.0, config=PresenceConfig(enter_rise_c=19.0, leave_rise_c=19.0))
    assert report["detection_rate"] == 0.0 and len(report["missed"]) == 3
    assert report["approach_latency_ms"] is None


@pytest.mark.slow
def test_default_detector_on_a_small_simulated_set():
    report = evaluate_presence(approach=12, empty=2, empty_s=300.0, seed=1)
    assert report["detection_rate"] >= 0.9
    assert report["false_alarms_per_hour"] == 0.0
    assert report["approach_latency_ms"]["median"] < 1000.0
    assert report["leave_latency_ms"]["median"] < 3000.0


def test_empty_clip_with_a_low_threshold_raises_false_alarms():
    clip = Clip("empty", 60.0, (), 22.0, 3)
    events = run_clip(clip, PresenceConfig(enter_rise_c=0.2, leave_rise_c=0.1, min_pixels=1, enter_frames=1), 8.0)
    assert any(e.phase == "approach" for e in events)


def test_a_room_as_warm_as_skin_hides_every_body():
    # no body is warmer than a 34.5 degC room: nothing to see, and nothing must be invented
    report = evaluate_presence(approach=3, empty=1, empty_s=30.0, room_c=(34.5, 34.5))
    assert report["room_c"] == [34.5, 34.5]
    assert report["detection_rate"] == 0.0 and report["false_alarms_per_hour"] == 0.0


def test_room_range_must_be_ordered():
    with pytest.raises(ValueError, match="room_c"):
        evaluate_presence(approach=1, empty=0, room_c=(26.0, 19.0))


def test_through_the_driver_the_same_visits_are_seen():
    """Raw words, ADC rounding, transport, driver and decoder between the scene and the detector."""
    direct = evaluate_presence(approach=2, empty=0, seed=2)
    chained = evaluate_presence(approach=2, empty=0, seed=2, through_driver=True)
    assert chained["through_driver"] and not direct["through_driver"]
    assert direct["detection_rate"] == chained["detection_rate"] == 1.0
    assert chained["false_alarms_in_approach_clips"] == 0
