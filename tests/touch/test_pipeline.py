"""TouchPipeline end to end on synthetic frames: the agreed interface and its robustness."""

import json

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline
from tests.touch.synth import H, ROI, W, Blob, Patch, backlight, render

CFG = TouchConfig(width=W, height=H)
DT = 1 / 15


def feed(pipe, frames, t0=0.0, dt=DT):
    results = []
    for k, frame in enumerate(frames):
        results.append(pipe.process(t0 + k * dt, frame))
    return results


def events_of(results):
    return [e for r in results for e in r.events]


@pytest.fixture(scope="module")
def light():
    return backlight()


def test_press_gives_down_and_up_with_camera_coordinates(light):
    rng = np.random.default_rng(3)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    frames = [render(light, rng=rng) for _ in range(10)]
    frames += [render(light, [Blob(60.4, 50.6, 0.85)], rng=rng) for _ in range(6)]
    frames += [render(light, rng=rng) for _ in range(8)]
    events = events_of(feed(pipe, frames))
    assert [e.phase for e in events] == ["down", "up"]
    down = events[0]
    assert abs(down.x - 60.4) < 0.5 and abs(down.y - 50.6) < 0.5
    assert down.u == pytest.approx((60.4 - ROI[0] + 0.5) / ROI[2], abs=0.01)
    assert events[1].kind == "tap"
    obj = down.to_json()
    assert set(obj) >= {"id", "phase", "kind", "t", "x", "y", "u", "v", "depth", "area", "anchor"}
    json.dumps(obj)


def test_bgr_frames_give_the_same_events(light):
    rng = np.random.default_rng(3)
    frames = [render(light, rng=rng) for _ in range(5)] + [render(light, [Blob(60, 50, 0.85)], rng=rng) for _ in range(5)]
    gray = events_of(feed(TouchPipeline(CFG, (W, H), ROI), frames))
    bgr = events_of(feed(TouchPipeline(CFG, (W, H), ROI), [cv2.cvtColor(f, cv2.COLOR_GRAY2BGR) for f in frames]))
    assert [(e.phase, round(e.x, 3)) for e in gray] == [(e.phase, round(e.x, 3)) for e in bgr]


def test_thirty_second_palm_press_stays_detected(light):
    rng = np.random.default_rng(4)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    feed(pipe, [render(light, rng=rng) for _ in range(10)])
    palm = [Patch(80, 60, 0.8, radius=14.0)]  # a palm pressed flat: a sharp-edged contact
    t0 = 10 * DT
    results = feed(pipe, [render(light, palm, rng=rng) for _ in range(450)], t0=t0)
    downs = [e for e in events_of(results) if e.phase == "down"]
    assert len(downs) == 1 and not any(e.phase == "up" for e in events_of(results))
    assert all(r.contacts for r in results[5:])  # still down after 30 s
    assert results[-1].area > 0.8 * results[10].area  # the reference has not eaten the shadow


def test_a_close_hover_as_deep_as_a_press_fires_nothing_while_the_press_does(light):
    # Same peak depth; the hover's shadow is blurred by its height, the press's edge is sharp.
    def run(shadow):
        rng = np.random.default_rng(5)
        pipe = TouchPipeline(CFG, (W, H), ROI)
        frames = [render(light, rng=rng) for _ in range(10)] + [render(light, [shadow], rng=rng) for _ in range(40)]
        return feed(pipe, frames)

    hover = run(Blob(80, 60, 0.8, sigma=14.0))
    press = run(Patch(80, 60, 0.7, radius=6.0))
    assert max(r.core_depth for r in hover) > CFG.instant_depth  # deep enough for the instant gate on depth alone
    assert events_of(hover) == [] and max(r.anchor for r in hover) == 0.0
    assert [e.phase for e in events_of(press)] == ["down"]
    assert max(r.edge for r in press) > 2 * CFG.contact_edge > 2 * max(r.edge for r in hover)


def test_exposure_drift_is_not_a_shadow(light):
    rng = np.random.default_rng(5)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    frames = [render(light, gain=1.0 + 0.4 * np.sin(k / 40), rng=rng) for k in range(200)]
    results = feed(pipe, frames)
    assert not events_of(results)
    assert not any(r.activity for r in results)


def test_lighting_step_reseeds_without_firing(light):
    rng = np.random.default_rng(6)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    frames = [render(light, rng=rng) for _ in range(20)]
    # A room light comes on: brighter and not multiplicative (an added glow from one side).
    glow = np.linspace(0, 40, W, dtype=np.float32)[None, :].repeat(H, 0)
    frames += [render(light * 1.3 + glow, rng=rng) for _ in range(40)]
    results = feed(pipe, frames)
    assert not events_of(results)
    assert pipe.light_changes >= 1  # the step re-seeded the reference (feelium.touch.illumination)
    assert not any(r.activity for r in results[22:])


def test_shadow_during_a_lighting_step_survives_it(light):
    rng = np.random.default_rng(7)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    press = [Blob(70, 55, 0.85)]
    frames = [render(light, rng=rng) for _ in range(10)] + [render(light, press, rng=rng) for _ in range(10)]
    frames += [render(light * 0.6, press, rng=rng) for _ in range(10)]
    results = feed(pipe, frames)
    assert pipe.light_changes == 1  # one step, one re-seed; the shadow kept under it
    assert [e.phase for e in events_of(results)] == ["down"]
    assert results[-1].contacts


@pytest.mark.parametrize("value", [0, 255])
def test_all_dark_and_all_saturated_frames(light, value):
    pipe = TouchPipeline(CFG, (W, H), ROI)
    rng = np.random.default_rng(8)
    frames = [render(light, rng=rng) for _ in range(5)] + [np.full((H, W), value, np.uint8)] * 20
    frames += [render(light, rng=rng) for _ in range(40)]
    results = feed(pipe, frames)
    for r in results:
        assert np.isfinite(r.anchor) and np.isfinite(r.depth_max)
    assert not events_of(results)


def test_starting_on_black_frames_then_light(light):
    pipe = TouchPipeline(CFG, (W, H), ROI)
    rng = np.random.default_rng(9)
    results = feed(pipe, [np.zeros((H, W), np.uint8)] * 5 + [render(light, rng=rng) for _ in range(30)])
    assert not events_of(results)


@given(st.lists(st.integers(0, 255), min_size=2, max_size=12), st.integers(0, 2**31 - 1))
def test_any_frame_sequence_gives_finite_results(levels, seed):
    pipe = TouchPipeline(CFG, (W, H), ROI)
    rng = np.random.default_rng(seed)
    for k, level in enumerate(levels):
        frame = np.clip(rng.normal(level, 30, (H, W)), 0, 255).astype(np.uint8)
        r = pipe.process(k * DT, frame)
        assert np.isfinite(r.anchor) and 0.0 <= r.depth_max <= 1.0 and r.area >= 0
        for e in r.events:
            assert all(np.isfinite([e.x, e.y, e.u, e.v, e.depth, e.anchor]))
    assert np.all(np.isfinite(pipe.reference.image))


def test_backwards_and_duplicate_timestamps_are_rejected_naming_both(light):
    pipe = TouchPipeline(CFG, (W, H), ROI)
    frame = render(light)
    pipe.process(1.0, frame)
    with pytest.raises(ValueError, match=r"0\.5.*1\.0"):
        pipe.process(0.5, frame)
    with pytest.raises(ValueError, match=r"1\.0.*1\.0"):
        pipe.process(1.0, frame)
    pipe.process(1.1, frame)  # still usable after a rejected frame


def test_gaps_are_handled(light):
    rng = np.random.default_rng(10)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    feed(pipe, [render(light, rng=rng) for _ in range(10)])
    press = [Blob(70, 55, 0.85)]
    times = [1.0, 1.07, 1.13, 3.0, 3.07, 3.13, 3.2, 6.0, 6.07, 6.13, 6.2]
    results = [pipe.process(t, render(light, press, rng=rng)) for t in times]
    results += [pipe.process(6.2 + 0.07 * k, render(light, rng=rng)) for k in range(1, 8)]
    phases = [e.phase for e in events_of(results) if e.phase != "move"]
    assert phases == ["down", "up"]  # one long press despite the gaps


def test_bad_frames_are_rejected_clearly(light):
    pipe = TouchPipeline(CFG, (W, H), ROI)
    with pytest.raises(ValueError, match="shape"):
        pipe.process(0.0, np.zeros((10, 10), np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        pipe.process(0.0, np.zeros((H, W), np.float32))
    with pytest.raises(ValueError, match="not finite"):
        pipe.process(float("nan"), render(light))


def test_roi_that_does_not_fit_is_rejected():
    with pytest.raises(ValueError, match="does not fit"):
        TouchPipeline(CFG, (W, H), (100, 100, 100, 100))


def test_shadow_outside_the_roi_is_ignored(light):
    rng = np.random.default_rng(11)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    frames = [render(light, rng=rng) for _ in range(5)] + [render(light, [Blob(5, 5, 0.9)], rng=rng) for _ in range(10)]
    assert not events_of(feed(pipe, frames))


def test_backlight_gain_is_divided_out(light):
    rng = np.random.default_rng(12)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    feed(pipe, [render(light, rng=rng) for _ in range(5)])
    # A projected face darkens half the membrane; the prediction says so, so it is not a shadow.
    pattern = np.ones((H, W), np.float32)
    pattern[:, : W // 2] = 0.5
    results = [pipe.process(1.0 + k * DT, render(light * pattern, rng=rng), pattern) for k in range(10)]
    assert not events_of(results) and not any(r.activity for r in results)
    bad = pattern.copy()
    bad[0, 0] = np.nan
    bad[1, 1] = -3.0
    r = pipe.process(2.0, render(light * pattern, rng=rng), bad)
    assert np.isfinite(r.depth_max)


def test_plain_baseline_agrees_with_the_fast_path(light):
    rng = np.random.default_rng(13)
    frames = [render(light, rng=rng) for _ in range(5)] + [render(light, [Blob(60.4, 50.6, 0.85)], rng=rng) for _ in range(5)]
    fast = events_of(feed(TouchPipeline(TouchConfig(width=W, height=H), (W, H), ROI), frames))
    plain = events_of(feed(TouchPipeline(TouchConfig(width=W, height=H), (W, H), ROI, plain=True), frames))
    assert [e.phase for e in fast] == [e.phase for e in plain] == ["down"]
    assert abs(fast[0].x - plain[0].x) < 0.3 and abs(fast[0].y - plain[0].y) < 0.3


def test_reset_forgets_time_and_reference(light):
    pipe = TouchPipeline(CFG, (W, H), ROI)
    pipe.process(5.0, render(light))
    pipe.reset()
    pipe.process(0.0, render(light))
    assert pipe.reference.image is not None
