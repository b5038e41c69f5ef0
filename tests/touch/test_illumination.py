"""Room-light changes: the re-seed detector (feelium.touch.illumination) and the pipeline through a switch."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from feelium.touch.config import TouchConfig
from feelium.touch.illumination import illumination_change, reseed, tile_px_for
from feelium.touch.pipeline import TouchPipeline
from tests.touch.synth import H, ROI, W, Blob, Patch, backlight, render

CFG = TouchConfig(width=W, height=H)
DT = 1 / 15
FLOOR = 0.07


def _uneven(h=96, w=128, ratio=4.0):
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((xs - w / 2) / (w / 2)) ** 2 + ((ys - h / 2) / (h / 2)) ** 2
    return (180.0 / (1.0 + (ratio - 1.0) * r2 / 2.0)).astype(np.float32)


def test_a_gain_step_keeps_the_shape_and_added_light_does_not():
    ref = _uneven()
    usable = np.ones(ref.shape, bool)
    assert illumination_change(ref * 1.6, ref, 1.0, usable, FLOOR) is None  # exposure: one factor
    lit = ref + 90.0  # a lamp adds the same light everywhere: the dim corners gain most
    change = illumination_change(lit, ref, 1.0, usable, FLOOR)
    assert change is not None and change[1].shape == ref.shape
    new = reseed(ref, lit, change, None)
    np.testing.assert_allclose(new, lit)


def test_a_large_hand_arriving_is_not_a_change_of_light():
    ref = _uneven()
    frame = ref.copy()
    frame[20:70, 30:90] *= 0.3  # a palm-sized shadow over about a third of the membrane
    assert illumination_change(frame, ref, 1.0, np.ones(ref.shape, bool), FLOOR) is None


def test_under_a_shadow_the_reseed_adds_the_smooth_room_light_and_scales_by_the_exposure():
    ref = _uneven()
    lit = (ref + 60.0) * 0.7  # a lamp switched on, and the auto-exposure already turned down
    shadow = np.zeros(ref.shape, bool)
    shadow[40:56, 56:72] = True
    frame = lit.copy()
    frame[shadow] *= 0.2
    usable = ~shadow
    change = illumination_change(frame, ref, 1.0, usable, FLOOR)
    assert change is not None
    new = reseed(ref, frame, change, shadow)
    # Inside the old shadow (at the back-light's bright centre) the new reference is the lit membrane: a ratio
    # interpolated from the dimmer tiles around it overestimated it by about 5 %, a false shadow a hover's depth
    # could land with.
    assert np.max(np.abs(new[shadow] / lit[shadow] - 1.0)) < 0.01


@settings(max_examples=60, deadline=None)
@given(
    frame=arrays(np.float32, (32, 48), elements=st.floats(0, 255, width=32)),
    ref=arrays(np.float32, (32, 48), elements=st.floats(1 / 64, 255, width=32)),
    gain=st.floats(1e-3, 1e3),
)
def test_any_input_gives_none_or_a_finite_map(frame, ref, gain):
    for force in (False, True):
        change = illumination_change(frame, ref, gain, ref >= 12.0, FLOOR, force=force)
        assert change is None or (
            np.isfinite(change[0]) and change[1].shape == frame.shape and np.isfinite(change[1]).all()
        )


def test_dark_saturated_and_nan_frames_give_nothing():
    ref = _uneven()
    none = np.zeros(ref.shape, bool)
    assert illumination_change(np.zeros_like(ref), ref, 1.0, none, FLOOR) is None
    nan = np.full(ref.shape, np.nan, np.float32)
    assert illumination_change(nan, ref, 1.0, np.ones(ref.shape, bool), FLOOR) is None


def _with_room(light, room, shadows, rng):
    """Back-light plus room light through the membrane; a contact blocks both at its core, a hover the room's."""
    frame = render(light, shadows, noise=2.0, rng=rng).astype(np.float32)
    lamp = np.full(light.shape, room, np.float32)
    for s in shadows:
        ys, xs = np.mgrid[0 : light.shape[0], 0 : light.shape[1]].astype(np.float32)
        sigma = s.sigma if isinstance(s, Blob) else 1.0
        radius = 0.0 if isinstance(s, Blob) else s.radius
        d = np.maximum(np.hypot(xs - s.x, ys - s.y) - radius, 0.0)
        lamp *= 1.0 - np.exp(-(d**2) / (2 * sigma**2))
    return np.clip(np.rint(frame + lamp), 0, 255).astype(np.uint8)


def test_a_lamp_switched_on_and_off_fires_nothing_and_a_press_held_through_it_stays_one_touch():
    light = backlight()
    rng = np.random.default_rng(7)
    pipe = TouchPipeline(CFG, (W, H), ROI)
    press = [Patch(80, 60, 0.7, radius=6.0)]
    events, t = [], 0.0
    # room light about the back-light's mean: a lit living room
    plan = [(0.0, [])] * 20 + [(0.0, press)] * 15 + [(120.0, press)] * 30 + [(120.0, [])] * 20 + [(0.0, [])] * 30
    results = []
    for room, shadows in plan:
        r = pipe.process(t, _with_room(light, room, shadows, rng))
        results.append(r)
        events += r.events
        t += DT
    assert [e.phase for e in events if e.phase in ("down", "up")] == ["down", "up"]
    assert pipe.light_changes >= 1  # the switch on; the switch off may be a plain exposure step
    assert not any(r.activity for r in results[-15:])  # within 1 s of the switch off the membrane is clean



BIG_W, BIG_H = 400, 300  # the default working size (320 x 240) over the ROI: the tile map has its real resolution
BIG_ROI = (40, 30, 320, 240)
BIG_CFG = TouchConfig(width=320, height=240)


def _hover_through(room_plan, rng_seed=11):
    """A close hover held at the back-light's bright centre while the room light follows ``room_plan``; then it
    leaves. Returns the pipeline's results."""
    light = backlight(BIG_W, BIG_H, ratio=5.0)
    rng = np.random.default_rng(rng_seed)
    pipe = TouchPipeline(BIG_CFG, (BIG_W, BIG_H), BIG_ROI)
    hover = [Blob(200, 150, 0.3, sigma=14.0)]  # blurred by its height: no contact edge
    results, t = [], 0.0
    for room, shadows in [(room_plan[0], [])] * 20 + [(r, hover) for r in room_plan] + [(room_plan[-1], [])] * 20:
        results.append(pipe.process(t, _with_room(light, room, shadows, rng)))
        t += DT
    return results


def test_a_hover_held_through_a_switch_keeps_its_depth_and_leaves_no_false_shadow():
    # Regression (lit-room experiment, s2-hover-001, switch-on and switch-off): the first frame of a lamp's ramp
    # re-based the reference under the hover by one exposure gain (then by a ratio interpolated from the dimmer
    # membrane around it); the false shadow left deepened the hover and sharpened its edge, and it fired. Through
    # a switch the hover must look as it does in steady light.
    for before, after in ((0.0, 60.0), (60.0, 0.0)):  # a lamp as bright as the back-light's mean
        ramp = [before] * 10 + [before + (after - before) * 0.25, before + (after - before) * 0.75] + [after] * 30
        steady = _hover_through([after] * len(ramp))
        switched = _hover_through(ramp)
        assert not [e for r in switched for e in r.events]
        hover_frames = slice(20 + 15, 20 + len(ramp))  # the hover in the new light, after the ramp
        deepest_steady = max(r.depth_max for r in steady[hover_frames])
        deepest_switched = max(r.depth_max for r in switched[hover_frames])
        assert abs(deepest_switched - deepest_steady) < 0.03, (before, after, deepest_switched, deepest_steady)
        assert not any(r.activity for r in switched[-10:])  # gone with the hand, no false shadow left behind


def test_the_tiles_are_the_same_part_of_the_membrane_at_any_detection_scale() -> None:
    """The room-light and share tiles stand for parts of the membrane: at ``detect_scale`` 0.5 they are half as many
    detection pixels a side, so there are as many of them over the ROI as at 1.0 (the median's breakdown point, a
    hand covering less than half of them, holds the same)."""
    from feelium.touch.roomshare import tile_grid

    assert (tile_px_for(1.0), tile_px_for(0.5), tile_px_for(0.25)) == (16, 8, 4)
    grids = set()
    for scale in (1.0, 0.5):
        pipe = TouchPipeline(TouchConfig(detect_scale=scale), (640, 480), (64, 48, 512, 384))
        w, h = pipe.geometry.work_size
        grids.add(tile_grid((h, w), pipe.projector_share.tile_px))
    assert grids == {(16, 12)}
