"""Presence detector: approach and leave with hysteresis, a baseline that follows the room but not a body."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.sim.thermal import ThermalSceneRenderer, WarmBody
from feelium.thermal.config import PresenceConfig
from feelium.thermal.presence import PresenceDetector, bearings, largest_warm_cluster

FPS = 8.0


def run(detector, renderer, bodies_at, duration, t0=0.0):
    events = []
    for i in range(int(duration * FPS)):
        t = t0 + i / FPS
        events += detector.step(t, renderer.frame(t, bodies_at(t)))
    return events


def test_bearings_through_the_d55_lens():
    assert bearings(15.5, 11.5, (55.0, 35.0)) == pytest.approx((0.0, 0.0), abs=1e-9)
    az, el = bearings(31.5, -0.5, (55.0, 35.0))  # the far right and top edges of the sensor
    assert az == pytest.approx(27.5, abs=1e-6) and el == pytest.approx(17.5, abs=1e-6)
    az, el = bearings(0.0, 23.0, (55.0, 35.0))
    assert az < -25 and el < -15


def test_cluster_centroid_and_size():
    rise = np.zeros((24, 32))
    rise[10:13, 20:24] = 3.0
    rise[0, 0] = 5.0  # a single hot pixel is not a body
    cluster, warm = largest_warm_cluster(rise, 1.0, 3)
    assert cluster.size == 12 and cluster.x == pytest.approx(21.5) and cluster.y == pytest.approx(11.0)
    assert cluster.peak_rise_c == 3.0 and warm.sum() == 13


def test_empty_room_with_drift_raises_nothing():
    renderer = ThermalSceneRenderer(np.random.default_rng(5), 22.0, drift_c=0.5, drift_period_s=120.0)
    detector = PresenceDetector()
    assert run(detector, renderer, lambda t: [], 240.0) == []


def test_hand_approaches_stays_and_leaves():
    renderer = ThermalSceneRenderer(np.random.default_rng(2), 22.0)

    def bodies(t):
        # 1.5 m away, in to touching by t=5, stays to t=15, out again by t=20
        d = 1500.0 * min(1.0, max(0.0, (5.0 - t) / 4.0, (t - 15.0) / 5.0))
        return [WarmBody(0.75, 0.3, d, 0.13)]

    detector = PresenceDetector()
    events = run(detector, renderer, bodies, 30.0)
    phases = [e.phase for e in events]
    assert phases[0] == "approach" and phases[-1] == "leave"
    assert phases.count("approach") == 1 and phases.count("leave") == 1
    assert all(p == "update" for p in phases[1:-1]) and len(phases) > 5
    approach, leave = events[0], events[-1]
    assert 5.0 > approach.t > 1.0  # seen on the way in, before touching
    assert 15.0 < leave.t < 21.0
    touching = [e for e in events if e.phase == "update" and 6.0 < e.t < 14.0]
    for e in touching:
        assert e.x == pytest.approx(0.75 * 32 - 0.5, abs=1.0) and e.y == pytest.approx(0.3 * 24 - 0.5, abs=1.0)
        assert e.azimuth_deg > 10 and e.elevation_deg > 3 and e.peak_rise_c > 4.0
    assert approach.to_json()["phase"] == "approach"


def test_body_that_stays_is_not_absorbed_into_the_baseline():
    renderer = ThermalSceneRenderer(np.random.default_rng(3), 22.0)
    detector = PresenceDetector(PresenceConfig(baseline_tau_s=10.0))
    events = run(detector, renderer, lambda t: [WarmBody(0.5, 0.5, 300.0, 0.5, 31.0)] if t > 2 else [], 180.0)
    assert [e.phase for e in events if e.phase != "update"] == ["approach"]
    assert detector.present


def test_a_single_warm_frame_is_not_a_visit():
    detector = PresenceDetector(PresenceConfig(enter_frames=2))
    room = np.full((24, 32), 22.0)
    hot = room.copy()
    hot[5:9, 5:9] = 30.0
    frames = [room, room, hot, room, room, room]
    events = [e for i, f in enumerate(frames) for e in detector.step(i / FPS, f)]
    assert events == [] and not detector.present


def test_leave_needs_several_empty_frames():
    detector = PresenceDetector(PresenceConfig(enter_frames=1, leave_frames=3, update_period_s=0.0))
    room = np.full((24, 32), 22.0)
    hot = room.copy()
    hot[5:9, 5:9] = 30.0
    frames = [room, hot, room, hot, room, room, room]
    phases = [(i, e.phase) for i, f in enumerate(frames) for e in detector.step(i / FPS, f)]
    assert phases == [(1, "approach"), (6, "leave")]


def test_nan_pixels_and_bad_frames_are_survived():
    detector = PresenceDetector(PresenceConfig(enter_frames=1))
    room = np.full((24, 32), 22.0)
    room[0, :] = np.nan
    detector.step(0.0, room)
    assert detector.step(0.1, np.zeros((3, 3))) == []
    assert detector.step(0.2, np.full((24, 32), np.nan)) == []
    assert detector.skipped == 2
    hot = room.copy()
    hot[10:14, 10:14] = 30.0
    assert [e.phase for e in detector.step(0.3, hot)] == ["approach"]


@given(seed=st.integers(0, 10_000), n=st.integers(1, 30))
def test_events_alternate_approach_then_leave(seed, n):
    rng = np.random.default_rng(seed)
    detector = PresenceDetector(PresenceConfig(enter_frames=1, leave_frames=1))
    phases = []
    for i in range(n):
        frame = 22.0 + rng.normal(0, 0.1, (24, 32))
        if rng.random() < 0.5:
            r, c = rng.integers(0, 20), rng.integers(0, 28)
            frame[r : r + 4, c : c + 4] += rng.uniform(0, 6)
        if rng.random() < 0.1:
            frame[rng.integers(0, 24), :] = np.nan
        phases += [e.phase for e in detector.step(i * 0.125, frame) if e.phase != "update"]
    assert all(a != b for a, b in zip(phases, phases[1:]))
    if phases:
        assert phases[0] == "approach"
    assert all(math.isfinite(v) for v in detector.baseline.ravel())
