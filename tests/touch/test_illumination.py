"""Room-light changes: the re-seed detector (feelium.touch.illumination) and the pipeline through a switch."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from feelium.touch.config import TouchConfig
from feelium.touch.illumination import illumination_change, reseed
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
    assert change is not None and change.shape == ref.shape
    new = reseed(ref, lit, change, None)
    np.testing.assert_allclose(new, lit)


def test_a_large_hand_arriving_is_not_a_change_of_light():
    ref = _uneven()
    frame = ref.copy()
    frame[20:70, 30:90] *= 0.3  # a palm-sized shadow over about a third of the membrane
    assert illumination_change(frame, ref, 1.0, np.ones(ref.shape, bool), FLOOR) is None


def test_under_a_shadow_the_reseed_scales_the_old_reference_by_the_smooth_change():
    ref = _uneven()
    lit = ref + 60.0
    shadow = np.zeros(ref.shape, bool)
    shadow[40:56, 56:72] = True
    frame = lit.copy()
    frame[shadow] *= 0.2
    usable = ~shadow
    change = illumination_change(frame, ref, 1.0, usable, FLOOR)
    assert change is not None
    new = reseed(ref, frame, change, shadow)
    # Inside the old shadow the new reference is close to the lit membrane (within the smooth map's error).
    assert np.max(np.abs(new[shadow] / lit[shadow] - 1.0)) < 0.05


@settings(max_examples=60, deadline=None)
@given(
    frame=arrays(np.float32, (32, 48), elements=st.floats(0, 255, width=32)),
    ref=arrays(np.float32, (32, 48), elements=st.floats(1 / 64, 255, width=32)),
    gain=st.floats(1e-3, 1e3),
)
def test_any_input_gives_none_or_a_finite_map(frame, ref, gain):
    change = illumination_change(frame, ref, gain, ref >= 12.0, FLOOR)
    assert change is None or (change.shape == frame.shape and np.isfinite(change).all())


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
