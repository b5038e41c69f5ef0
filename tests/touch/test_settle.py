"""The uncertain-frame rule (feelium.touch.settle, Tracker.step(settled=False)) and the face on the skin end to end."""

from __future__ import annotations

import numpy as np

from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline
from feelium.touch.settle import PredictionSettle
from feelium.touch.tracker import Observation, Tracker
from tests.touch import faceon_synth as face
from tests.touch.synth import H, ROI, W

CFG = TouchConfig(width=W, height=H)


def test_a_cut_is_uncertain_until_it_settles() -> None:
    s = PredictionSettle(cut_change=0.04, settle_s=0.25)
    a, b = np.full((8, 8), 1.0, np.float32), np.full((8, 8), 0.5, np.float32)
    assert s.observe(0.0, a) and s.observe(0.1, a)
    assert not s.observe(0.2, b)  # the cut
    assert not s.observe(0.3, b)
    assert s.observe(0.46, b)  # 0.26 s after the cut
    assert s.uncertain_frames == 1


def test_a_small_local_change_keeps_the_frame_certain() -> None:
    s = PredictionSettle(cut_change=0.04, settle_s=0.25)
    a = np.ones((40, 40), np.float32)
    b = a.copy()
    b[10:16, 10:20] = 0.05  # a mouth opening: 60 of 1600 px
    assert s.observe(0.0, a) and s.observe(0.1, b)


def test_nan_light_counts_as_uncertain() -> None:
    s = PredictionSettle(cut_change=0.04, settle_s=0.25)
    a = np.ones((4, 4), np.float32)
    s.observe(0.0, a)
    assert not s.observe(0.1, np.full((4, 4), np.nan, np.float32))


def test_unsettled_frames_raise_no_touch_but_hold_one_that_is_down() -> None:
    cfg = TouchConfig(anchor_min_age_s=0.0)
    press = Observation(50.0, 50.0, 0.5, 0.5, depth=0.8, area=100, edge=0.2)
    held = Tracker(cfg)
    events = [e for i in range(4) for e in held.step(i / 15, [press], settled=i < 3).events]
    assert [e.phase for e in events] == ["down"]  # down before the cut, held through it
    fresh = Tracker(cfg)
    assert not [e for i in range(6) for e in fresh.step(i / 15, [press], settled=False).events]
    after = [e for i in range(6, 9) for e in fresh.step(i / 15, [press]).events]
    assert [e.phase for e in after] == ["down"]  # raised once settled


def _clip(pipeline: TouchPipeline, seconds: float, *, hover: bool, press_at: tuple[float, float] | None, compensate: bool):
    rng = np.random.default_rng(11)
    events = []
    for t in np.arange(0.0, seconds, 1 / 15):
        light = face.face_light(float(t))
        h = (80.0 + 15 * np.sin(3 * t), 60.0, 0.8) if hover and t > 4.0 else None
        p = (70.0, 55.0) if press_at is not None and press_at[0] <= t < press_at[1] else None
        frame = face.frame(float(t), light, hover=h, press=p, rng=rng)
        kwargs = {"projected_light": light} if compensate else {"backlight_gain": light}
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


def test_dividing_the_face_out_fires_on_the_same_hover() -> None:
    """The multiplicative model (divide by the light) turns the room light behind a dark face into shadows."""
    events = _clip(TouchPipeline(CFG, (W, H), ROI), 9.0, hover=True, press_at=None, compensate=False)
    assert any(e.phase == "down" for e in events)
