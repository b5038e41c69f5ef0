"""The sensor model: noise statistics, clipping, frame timing."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.sim.camera import SensorParams, expose, frame_times, gain_at


@pytest.mark.parametrize("level", [20.0, 80.0, 160.0])
def test_noise_variance_is_shot_plus_read(level: float) -> None:
    p = SensorParams(shot_dn=0.5, read_dn=2.0)
    frame = expose(np.full((200, 300), level, np.float32), p, np.random.default_rng(1)).astype(np.float64)
    assert frame.mean() == pytest.approx(level, abs=0.2)
    expected = p.shot_dn * level + p.read_dn**2 + 1 / 12  # + rounding
    assert frame.var() == pytest.approx(expected, rel=0.05)


def test_eight_bit_clipping() -> None:
    frame = expose(np.array([[-20.0, 300.0, 128.0]], np.float32), SensorParams(read_dn=0.1, shot_dn=0.0), np.random.default_rng(0))
    assert frame.dtype == np.uint8 and frame.tolist() == [[0, 255, 128]]


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31), st.floats(2.0, 80.0))
def test_frame_times_increase_with_jitter_and_drops(seed: int, duration: float) -> None:
    p = SensorParams(jitter_ms=4.0, drop_rate=0.05)
    ts = frame_times(p, duration, np.random.default_rng(seed))
    assert ts[0] < 0.03 and np.all(np.diff(ts) > 0) and ts[-1] < duration
    assert len(ts) <= int(duration * p.fps)


def test_jitter_and_drop_statistics() -> None:
    p = SensorParams(jitter_ms=3.0, drop_rate=0.02)
    ts = frame_times(p, 2000.0, np.random.default_rng(5))
    period = 1 / p.fps
    slot = np.rint(ts / period)
    residual = ts - slot * period
    assert residual.std() * 1e3 == pytest.approx(3.0, rel=0.1)
    dropped = 1 - len(ts) / (2000.0 * p.fps)
    assert dropped == pytest.approx(0.02, abs=0.004)
    gaps = np.diff(slot)
    assert gaps.max() >= 2  # some frame slots pass empty


def test_gain_drifts_slowly_within_its_amplitude() -> None:
    p = SensorParams(drift_amp=0.03, drift_period_s=40.0)
    g = np.array([gain_at(p, t, 0.4) for t in np.arange(0, 120, 1 / 15)])
    assert g.max() <= 1.03 + 1e-9 and g.min() >= 0.97 - 1e-9 and g.max() - g.min() > 0.02
    assert np.abs(np.diff(g)).max() < 0.002  # slow: tiny change frame to frame


def test_bench_reports_every_scene_against_the_baseline() -> None:
    from feelium.lab.sim.bench import format_table, run_bench

    report = run_bench(frames=5)
    scenes = report["scenes"]
    assert scenes["empty (baseline)"]["ratio"] == 1.0 and {"pressed", "hover", "swipe", "sweep", "body"} <= set(scenes)
    assert all(s["median_ms"] > 0 for s in scenes.values()) and "ffv1 encode" in format_table(report)
