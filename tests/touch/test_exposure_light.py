"""ExposureLight predicts each projector frame once, and a frame shown again (the same array) not at all."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.touch.config import TouchConfig
from feelium.touch.projected import ExposureLight


def _predict(frame: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    return np.full((3, 4), float(frame.mean()) / 100.0, np.float32)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.lists(st.booleans(), min_size=2, max_size=40))
def test_a_repeated_frame_gets_the_same_light_without_a_new_prediction(seed, repeats):
    rng = np.random.default_rng(seed)
    config = TouchConfig()
    memo, fresh = ExposureLight(_predict, config), ExposureLight(_predict, config)
    frames: list[tuple[float, int, np.ndarray]] = []
    copies: list[tuple[float, int, np.ndarray]] = []  # the same frames, each its own array: no repeat to notice
    current = rng.integers(0, 255, (6, 8, 3), np.uint8)
    distinct = 1
    for i, repeat in enumerate(repeats):
        if not repeat and i:
            current, distinct = rng.integers(0, 255, (6, 8, 3), np.uint8), distinct + 1
        frames = (frames + [(i / 30.0, i + 1, current)])[-12:]
        copies = (copies + [(i / 30.0, i + 1, current.copy())])[-12:]
        t = i / 30.0 + config.projector_latency_s
        got, want = memo(frames, t), fresh(copies, t)
        assert got is not None and want is not None
        np.testing.assert_allclose(got[0], want[0], rtol=1e-6)
        np.testing.assert_allclose(got[1], want[1], rtol=1e-6, atol=1e-7)
    assert memo.predicted == distinct and fresh.predicted == len(repeats)


def _predict_into(frame: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """As _predict, writing into ``out`` when given (as CanvasLightPredictor.gain does)."""
    out = np.empty((3, 4), np.float32) if out is None else out
    out.fill(float(frame.mean()) / 100.0)
    return out


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.lists(st.booleans(), min_size=2, max_size=40))
def test_recycled_lights_give_what_fresh_ones_give(seed, repeats):
    """Predicting into the arrays of frames that left the window never overwrites a light still in use."""
    rng = np.random.default_rng(seed)
    config = TouchConfig()
    recycled, fresh = ExposureLight(_predict_into, config), ExposureLight(_predict, config)
    frames: list[tuple[float, int, np.ndarray]] = []
    current = rng.integers(0, 255, (6, 8, 3), np.uint8)
    for i, repeat in enumerate(repeats):
        if not repeat and i:
            current = rng.integers(0, 255, (6, 8, 3), np.uint8)
        frames = (frames + [(i / 30.0, i + 1, current)])[-int(rng.integers(2, 8)) :]
        t = i / 30.0 + config.projector_latency_s
        got, want = recycled(frames, t), fresh(frames, t)
        assert got is not None and want is not None
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])


def _window_and_whole(seed: int, count: int, r0: int, c0: int, by_mix: bool) -> tuple[np.ndarray, np.ndarray]:
    """A window of the exposure's light, predicted by window (``by_mix``: the exposure's frames and weights handed
    over at once), and the same window of the mix of the finer whole lights."""
    rng = np.random.default_rng(seed)
    config = TouchConfig()
    finer: dict[int, np.ndarray] = {}

    def fine(frame: np.ndarray) -> np.ndarray:
        return finer.setdefault(id(frame), rng.random((6, 8)).astype(np.float32))

    def mixed(parts, rows, cols):
        return sum(np.float32(w) * fine(frame)[rows, cols] for frame, w in parts)

    frames = [(i / 30.0, i + 1, rng.integers(0, 255, (6, 8, 3), np.uint8)) for i in range(count)]
    if by_mix:
        light = ExposureLight(_predict, config, mixed_window=mixed)
    else:
        light = ExposureLight(_predict, config, lambda frame, rows, cols: fine(frame)[rows, cols])
    whole = ExposureLight(lambda frame, out: fine(frame), config)
    t = (count - 1) / 30.0 + config.projector_latency_s + float(rng.uniform(-0.02, 0.02))
    assert light.window(slice(0, 2), slice(0, 2)) is None  # no exposure asked for yet
    assert light(frames, t) is not None
    expected = whole(frames, t)
    assert expected is not None
    window = (slice(r0, 6), slice(c0, 8))
    got = light.window(*window)
    assert got is not None
    return got, expected[0][window]


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 8), st.integers(0, 5), st.integers(0, 7))
def test_a_window_is_the_finer_whole_lights_mix_there(seed, count, r0, c0):
    """The fine pass's window: the same frames, the same weights as the exposure's mix, at the finer size."""
    got, expected = _window_and_whole(seed, count, r0, c0, by_mix=False)
    np.testing.assert_array_equal(got, expected)
    assert ExposureLight(_predict, TouchConfig()).window(slice(r0, 6), slice(c0, 8)) is None  # no window predictor


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 8), st.integers(0, 5), st.integers(0, 7))
def test_a_window_by_mix_gets_the_exposures_frames_and_weights(seed, count, r0, c0):
    """With ``mixed_window`` the predictor is handed the exposure's frames and weights at once (and computes the
    mix), giving the finer whole lights' mix there."""
    got, expected = _window_and_whole(seed, count, r0, c0, by_mix=True)
    np.testing.assert_allclose(got, expected, rtol=1e-6)
