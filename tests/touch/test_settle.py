"""The prediction's spread (feelium.touch.settle), Tracker.step(settled=False), and the face on the skin end to end."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline
from feelium.touch.settle import depth_uncertainty, predicted_exposure
from feelium.touch.tracker import Observation, Tracker
from tests.touch import faceon_synth as face
from tests.touch.synth import H, ROI, W

CFG = TouchConfig(width=W, height=H)
FPS = 30.0


def _cut_at(k_cut: int):
    """Projector frames: scene A (light 1.0) before frame ``k_cut``, scene B (0.4) from it."""
    a, b = np.full((4, 4), 1.0, np.float32), np.full((4, 4), 0.4, np.float32)
    return lambda k: a if k < k_cut else b


def _regular(t: float) -> list[tuple[float, int]]:
    """The 30 fps projector frames around camera time ``t``."""
    k = int(np.floor(t * FPS))
    return [(i / FPS, i) for i in range(k - 4, k + 2)]


def test_spread_is_zero_inside_a_scene_and_large_only_on_the_frame_that_straddles_a_cut() -> None:
    light_of = _cut_at(30)  # the cut lights the membrane from 1.0 s + latency
    kw = dict(exposure_s=0.03, latency_s=0.033, latency_sigma_s=0.0167)
    light, spread = predicted_exposure(_regular(0.5), light_of, 0.5, **kw)
    assert np.allclose(light, 1.0) and np.all(spread == 0.0)
    light, spread = predicted_exposure(_regular(1.033), light_of, 1.033, **kw)  # exposure centred on the cut
    assert np.allclose(light, 0.7, atol=1e-5)
    assert np.allclose(spread, 0.3, atol=1e-5)  # a 16.7 ms shift moves half of the 30 ms exposure to one scene
    light, spread = predicted_exposure(_regular(1.2), light_of, 1.2, **kw)
    assert np.allclose(light, 0.4) and np.all(spread == 0.0)


def test_a_fade_is_nearly_certain() -> None:
    """Light that changes smoothly moves little with the latency: a fade keeps touches visible."""
    fade = lambda k: np.full((2, 2), max(0.0, 1.0 - k / 12.0), np.float32)  # to black over 0.4 s
    _, spread = predicted_exposure(_regular(0.2), fade, 0.2, exposure_s=0.03, latency_s=0.033, latency_sigma_s=0.0167)
    assert float(spread.max()) <= 0.05


def test_irregular_frames_mix_by_their_own_times() -> None:
    """The daemon's projector frames come when they come: each lights from its own time to the next one's."""
    light_of = {"a": np.full((2, 2), 1.0, np.float32), "b": np.full((2, 2), 0.0, np.float32)}.__getitem__
    frames = [(0.0, "a"), (0.050, "b")]  # "a" shown for 50 ms, then "b" until further notice
    light, _ = predicted_exposure(frames, light_of, 0.080, exposure_s=0.04, latency_s=0.02, latency_sigma_s=0.0)
    assert np.allclose(light, 0.25)  # exposure 40..80 ms on the projector's clock: 10 ms of "a", 30 ms of "b"
    light, _ = predicted_exposure(frames, light_of, 0.020, exposure_s=0.0, latency_s=0.02, latency_sigma_s=0.0)
    assert np.allclose(light, 1.0)


def test_no_latency_uncertainty_means_no_spread() -> None:
    _, spread = predicted_exposure(_regular(1.033), _cut_at(30), 1.033, exposure_s=0.03, latency_s=0.033, latency_sigma_s=0.0)
    assert np.all(spread == 0.0)


@settings(max_examples=60, deadline=None)
@given(
    spread=arrays(np.float32, (6, 7), elements=st.floats(-1e6, 1e6, width=32) | st.just(np.nan) | st.just(np.inf)),
    slope=arrays(np.float32, (6, 7), elements=st.floats(-1e6, 1e6, width=32) | st.just(np.nan)),
    expected=arrays(np.float32, (6, 7), elements=st.floats(0.0625, 1e4, width=32)),
    sigma=st.sampled_from([0.0, 1.0, 2.5]),
)
def test_depth_uncertainty_is_finite_and_within_zero_and_one(spread, slope, expected, sigma) -> None:
    bound = depth_uncertainty(spread, slope, expected, sigma)
    assert bound.shape == spread.shape and np.all(np.isfinite(bound))
    assert float(bound.min()) >= 0.0 and float(bound.max()) <= 1.0 + 1e-6


def test_depth_uncertainty_bounds_the_smoothed_error() -> None:
    """Whatever the sign pattern of an error within the spread, its smoothed depth stays under the bound."""
    rng = np.random.default_rng(3)
    spread = rng.uniform(0.0, 0.3, (40, 50)).astype(np.float32)
    slope = rng.uniform(20.0, 80.0, (40, 50)).astype(np.float32)
    expected = np.full((40, 50), 120.0, np.float32)
    bound = depth_uncertainty(spread, slope, expected, 2.0)
    for _ in range(5):
        error = spread * rng.choice([-1.0, 1.0], spread.shape).astype(np.float32)
        depth = cv2.GaussianBlur(error * slope / expected, (0, 0), 2.0, borderType=cv2.BORDER_REPLICATE)
        assert np.all(np.abs(depth) <= bound + 1e-5)


def test_unsettled_frames_raise_no_touch_but_hold_one_that_is_down() -> None:
    cfg = TouchConfig(anchor_min_age_s=0.0)
    press = Observation(50.0, 50.0, 0.5, 0.5, depth=0.8, area=100, edge=0.2)
    held = Tracker(cfg)
    events = [e for i in range(4) for e in held.step(i / 15, [press], settled=i < 3).events]
    assert [e.phase for e in events] == ["down"]  # down before, held through
    fresh = Tracker(cfg)
    assert not [e for i in range(6) for e in fresh.step(i / 15, [press], settled=False).events]
    after = [e for i in range(6, 9) for e in fresh.step(i / 15, [press]).events]
    assert [e.phase for e in after] == ["down"]  # raised once settled


def _clip(
    pipeline: TouchPipeline,
    seconds: float,
    *,
    hover: bool,
    press_at: tuple[float, float] | None,
    compensate: bool,
    error: float = 0.0,
    press_xy: tuple[float, float] = (70.0, 55.0),
):
    """``error``: the projector's real latency minus the assumed one, in seconds (the prediction is that late)."""
    rng = np.random.default_rng(11)
    events = []
    for t in np.arange(0.0, seconds, 1 / 15):
        light = face.face_light(float(t) - error)
        predicted = face.face_light(float(t))
        h = (80.0 + 15 * np.sin(3 * t), 60.0, 0.8) if hover and t > 4.0 else None
        p = press_xy if press_at is not None and press_at[0] <= t < press_at[1] else None
        frame = face.frame(float(t), light, hover=h, press=p, rng=rng)
        if compensate:
            spread = np.abs(face.face_light(float(t) - 0.0167) - predicted)
            np.maximum(spread, np.abs(face.face_light(float(t) + 0.0167) - predicted), out=spread)
            kwargs = {"projected_light": predicted, "projected_spread": spread}
        else:
            kwargs = {"backlight_gain": predicted}
        events += pipeline.process(float(t), frame, **kwargs).events
    return events + list(pipeline.finish())


def test_face_on_hover_fires_nothing_and_a_press_is_found() -> None:
    """End to end on a short synthetic face clip (talking, sway, cuts, a fade): hover silent, press found."""
    hover = _clip(TouchPipeline(CFG, (W, H), ROI), 9.0, hover=True, press_at=None, compensate=True)
    assert hover == []
    press = _clip(TouchPipeline(CFG, (W, H), ROI), 7.0, hover=False, press_at=(5.0, 6.0), compensate=True)
    downs = [e for e in press if e.phase == "down"]
    assert len(downs) == 1
    assert abs(downs[0].x - 70.0) <= 3.0 and abs(downs[0].y - 55.0) <= 3.0


@pytest.mark.parametrize("detect_scale", [1.0, 0.5])
def test_a_late_prediction_at_cuts_fires_nothing_and_a_press_across_a_cut_is_found(detect_scale: float) -> None:
    """The light is 10 ms later than predicted: the cuts' errors stay within the spread; a press over a cut (at
    6 s) is raised without waiting for anything to settle. At 0.5 too (with room-light tiles of 16 detection
    pixels, four times larger on the membrane, a cut re-seeded the reference under the press and it was lost)."""
    cfg = dataclasses.replace(CFG, detect_scale=detect_scale)
    idle = _clip(TouchPipeline(cfg, (W, H), ROI), 9.0, hover=False, press_at=None, compensate=True, error=0.010)
    assert idle == []
    at = (105.0, 27.0)  # on the face in both framings
    press = _clip(
        TouchPipeline(cfg, (W, H), ROI), 7.0, hover=False, press_at=(5.9, 6.2), compensate=True, error=0.010, press_xy=at
    )
    downs = [e for e in press if e.phase == "down"]
    assert len(downs) == 1 and downs[0].t <= 6.1  # the old rule held every new touch until 6.25 s
    assert abs(downs[0].x - at[0]) <= 3.0 and abs(downs[0].y - at[1]) <= 3.0


def test_dividing_the_face_out_fires_on_the_same_hover() -> None:
    """The multiplicative model (divide by the light) turns the room light behind a dark face into shadows."""
    events = _clip(TouchPipeline(CFG, (W, H), ROI), 9.0, hover=True, press_at=None, compensate=False)
    assert any(e.phase == "down" for e in events)


def test_an_unknown_spread_hides_every_shadow_and_teaches_nothing() -> None:
    """NaN spread (the prediction cannot say how good it is) counts as fully uncertain, never as certain."""
    pipeline = TouchPipeline(CFG, (W, H), ROI)
    rng = np.random.default_rng(5)
    flat = np.ones((H, W), np.float32)
    unknown = np.full((H, W), np.nan, np.float32)
    for i in range(60):
        t = i / 15
        press = (70.0, 55.0) if t >= 3.0 else None
        frame = face.frame(t, flat, press=press, rng=rng)
        result = pipeline.process(t, frame, projected_light=flat, projected_spread=unknown if t >= 3.0 else None)
        assert np.isfinite(result.depth_max)
        if t >= 3.0:
            assert result.events == () and result.depth_max == 0.0
