"""The per-pixel projector response (feelium.touch.photometric): learned from frames, safe on any input."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from feelium.touch.photometric import INITIAL_SHARE, ProjectorResponse

SHAPE = (40, 48)


def _response() -> ProjectorResponse:
    return ProjectorResponse(tau_s=20.0, prior_var=0.01)


def test_learns_gain_and_share_of_an_affine_response() -> None:
    """frame = a * light + c per pixel: the slope and the pooled share a / (a + c) come out within 2 %."""
    rng = np.random.default_rng(3)
    a = rng.uniform(40.0, 120.0, SHAPE).astype(np.float32)
    c = (a * 1.2).astype(np.float32)  # room light: share = 1 / 2.2
    r = _response()
    usable = np.ones(SHAPE, bool)
    for i in range(200):
        light = rng.uniform(0.04, 1.4, SHAPE).astype(np.float32)
        r.learn(i / 15.0, a * light + c + rng.normal(0, 0.5, SHAPE).astype(np.float32), light, usable)
    assert r.share is not None and abs(r.share - 1 / 2.2) < 0.01
    assert r.slope is not None
    assert np.median(np.abs(r.slope / a - 1)) < 0.02
    light = np.full(SHAPE, 0.05, np.float32)
    flat = r.compensate(a * light + c, light)  # what flat grey would have given: a + c
    assert np.median(np.abs(flat / (a + c) - 1)) < 0.01


def test_pixels_whose_light_never_changes_use_the_pooled_share() -> None:
    """A pixel always black learns no slope from its own data; the pooled share keeps it bounded."""
    rng = np.random.default_rng(4)
    a, c = np.float32(100.0), np.float32(100.0)
    r = _response()
    for i in range(150):
        light = rng.uniform(0.04, 1.4, SHAPE).astype(np.float32)
        light[:4, :4] = 0.04  # a region of the face that stays black
        r.learn(i / 15.0, a * light + c, light, np.ones(SHAPE, bool))
    assert r.slope is not None
    assert abs(float(r.slope[0, 0]) / a - 1.0) < 0.1  # the multiplicative model would say (4 + 100) / 0.04 = 26x


def test_initial_slope_is_bounded_by_the_initial_share() -> None:
    r = _response()
    frame = np.full(SHAPE, 100.0, np.float32)
    out = r.compensate(frame, np.zeros(SHAPE, np.float32))
    assert r.share is None
    assert np.allclose(out, frame * (1 + INITIAL_SHARE / (1 - INITIAL_SHARE)))


values = st.floats(allow_nan=True, allow_infinity=True, width=32)


@settings(max_examples=60, deadline=None)
@given(
    frame=arrays(np.float32, SHAPE, elements=values),
    light=arrays(np.float32, SHAPE, elements=values),
    usable=arrays(np.bool_, SHAPE),
)
def test_any_input_leaves_a_finite_model(frame: np.ndarray, light: np.ndarray, usable: np.ndarray) -> None:
    """NaN, infinities, black and saturated values never make the learned slope non-finite."""
    r = _response()
    base = np.full(SHAPE, 100.0, np.float32)
    ok = np.linspace(0.05, 1.5, SHAPE[0] * SHAPE[1], dtype=np.float32).reshape(SHAPE)
    r.learn(0.0, base * ok + 50, ok, np.ones(SHAPE, bool))
    r.learn(0.1, frame, light, usable)
    r.learn(0.2, np.zeros(SHAPE, np.float32), np.zeros(SHAPE, np.float32), np.ones(SHAPE, bool))
    r.learn(0.3, np.full(SHAPE, 255.0, np.float32), np.full(SHAPE, 16.0, np.float32), np.ones(SHAPE, bool))
    assert r.slope is not None and np.isfinite(r.slope).all()
    assert r.share is None or np.isfinite(r.share)
