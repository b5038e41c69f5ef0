"""The touch side's projector history: bounded by the exposure/latency window, and never short of a canvas."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.touch.config import TouchConfig
from feelium.touch.projected import HISTORY_MAX, LATE_S, ExposureLight, ProjectorHistory, history_window_s

CANVAS = (384, 512)


def test_at_30_fps_six_canvases_are_kept_at_most_twelve_at_any_rate():
    config = TouchConfig()
    window = history_window_s(config)
    assert math.isclose(window, 0.015 + 0.033 + 0.0167 + LATE_S)
    for fps, want in ((30.0, 6), (15.0, 4), (240.0, HISTORY_MAX)):  # floor(window * fps) + 2, capped
        history = ProjectorHistory(window)
        canvas = np.zeros(CANVAS, np.uint8)
        for i in range(200):
            history.record(i / fps, i + 1, canvas)
        assert len(history.frames()) == want, fps
    held = ProjectorHistory(window)
    for i in range(200):
        held.record(i / 240.0, i + 1, np.zeros(CANVAS, np.uint8))
    assert sum(c.nbytes for _, _, c in held.frames()) <= HISTORY_MAX * 512 * 384  # 3.1 MB, was 12 x 2.7 MB


def _predict(canvas: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    return np.full((3, 4), float(canvas[0, 0]) / 100.0, np.float32)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(10.0, 40.0))
def test_the_bounded_history_mixes_what_the_whole_history_mixes(seed, fps):
    """A camera frame processed up to LATE_S after its exposure's centre gets the same light and spread from
    the bounded history as from every canvas ever shown (jittered projector frames, repeated ones included)."""
    rng = np.random.default_rng(seed)
    config = TouchConfig()
    history = ProjectorHistory(history_window_s(config))
    everything: list[tuple[float, int, np.ndarray]] = []
    bounded, whole = ExposureLight(_predict, config), ExposureLight(_predict, config)
    t, canvas = 0.0, np.zeros((2, 2), np.uint8)
    for seq in range(1, 80):
        t += float(rng.uniform(0.6, 1.4)) / fps
        if rng.random() < 0.7:
            canvas = np.full((2, 2), int(rng.integers(0, 256)), np.uint8)
        history.record(t, seq, canvas)
        everything.append((t, seq, canvas))
        camera_t = t - float(rng.uniform(0.0, LATE_S))  # the newest canvas was shown up to LATE_S after it
        got, want = bounded(history.frames(), camera_t), whole(everything, camera_t)
        assert got is not None and want is not None
        np.testing.assert_allclose(got[0], want[0], rtol=1e-6)
        np.testing.assert_allclose(got[1], want[1], rtol=1e-6, atol=1e-7)
