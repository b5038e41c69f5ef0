"""Adaptive reference: follows slow change, ignores shadows, re-baselines on steps, never drifts."""

import numpy as np
import pytest

from feelium.touch.reference import REFERENCE_FLOOR, AdaptiveReference


def make(**kw):
    args = dict(
        tau_s=4.0, bright_tau_s=0.5, forced_tau_s=90.0, dark_level=12.0, saturation_level=250.0,
        rebaseline_step=0.12, sample_step=1,
    )
    args.update(kw)
    return AdaptiveReference(**args)


def test_follows_the_frame_where_unshadowed_and_freezes_under_shadow():
    ref = make()
    base = np.full((8, 8), 100.0, np.float32)
    ref.initialise(0.0, base)
    shadow = np.zeros((8, 8), bool)
    shadow[:4] = True
    anchored = shadow.copy()
    frame = np.full((8, 8), 80.0, np.float32)
    for k in range(1, 600):
        ref.update(k / 15, frame, shadow, anchored)
    assert np.allclose(ref.image[4:], 80.0, atol=0.1)
    assert np.all(ref.image[:4] == 100.0)


def test_unanchored_shadow_is_forced_slowly():
    ref = make(forced_tau_s=10.0)
    ref.initialise(0.0, np.full((4, 4), 100.0, np.float32))
    shadow = np.ones((4, 4), bool)
    ref.update(10.0, np.full((4, 4), 50.0, np.float32), shadow, None)
    assert np.allclose(ref.image, 50.0 + 50.0 * np.exp(-1.0), atol=0.01)


def test_gain_is_robust_to_a_shadow():
    ref = make()
    base = np.linspace(40, 220, 400, dtype=np.float32).reshape(20, 20)
    ref.initialise(0.0, base)
    frame = base * 1.3
    frame[5:10, 5:10] *= 0.2  # a shadow covering 6 % of the pixels
    assert ref.measure_gain(frame, None) == pytest.approx(1.3, rel=1e-3)


def test_gain_keeps_its_value_when_nothing_is_usable():
    ref = make()
    ref.initialise(0.0, np.full((4, 4), 100.0, np.float32))
    assert ref.measure_gain(np.full((4, 4), 255.0, np.float32), None) == 1.0  # all saturated
    assert ref.measure_gain(np.zeros((4, 4), np.float32), np.ones((4, 4), bool)) == 1.0  # all shadowed


def test_black_frame_is_a_lighting_step_to_the_gain_floor():
    ref = make()
    ref.initialise(0.0, np.full((4, 4), 100.0, np.float32))
    assert ref.measure_gain(np.zeros((4, 4), np.float32), None) == pytest.approx(1e-3)


def test_lighting_step_rebaselines_outside_shadows():
    ref = make()
    ref.initialise(0.0, np.full((6, 6), 100.0, np.float32))
    shadow = np.zeros((6, 6), bool)
    shadow[0, 0] = True
    frame = np.full((6, 6), 160.0, np.float32)
    frame[0, 0] = 40.0
    assert ref.observe_gain(1.6, frame, shadow)
    assert ref.gain == 1.0 and ref.rebaselines == 1
    assert ref.image[0, 0] == pytest.approx(160.0)  # old reference times the new gain
    assert ref.image[3, 3] == 160.0
    assert not ref.observe_gain(1.05, frame, shadow)


@pytest.mark.slow
def test_a_million_updates_neither_drift_nor_denormalise():
    ref = make()
    frame = np.array([[100.0, 37.25], [0.0, 255.0]], np.float32)
    ref.initialise(0.0, frame)
    shadow = np.zeros((2, 2), bool)
    dt = 0.0625  # exact in binary, so every step has the same rate
    for k in range(1, 1_000_001):
        ref.update(k * dt, frame, shadow, None)
    image = ref.image
    assert image[0, 0] == pytest.approx(100.0, abs=1e-3)
    assert image[0, 1] == pytest.approx(37.25, abs=1e-3)
    assert image[1, 0] == REFERENCE_FLOOR  # decayed to the floor, not through denormals
    assert np.all(np.abs(image) >= np.finfo(np.float32).tiny)


def test_carry_moves_the_image_by_the_change_in_gain_free_units_shadows_included_and_keeps_the_floor():
    """The compensation moved every later frame by ``change``: a frame at gain 2 moves by it, the image (kept at gain
    1) by half of it, under a shadow too; a change that would go below zero stops at the floor."""
    ref = make()
    ref.initialise(0.0, np.full((4, 4), 100.0, np.float32))
    ref.gain = 2.0
    change = np.zeros((4, 4), np.float32)
    change[0] = -30.0
    change[1] = 10.0
    change[2] = -1000.0
    ref.carry(change)
    assert np.allclose(ref.image[0], 85.0) and np.allclose(ref.image[1], 105.0)
    assert np.all(ref.image[2] == np.float32(REFERENCE_FLOOR))
    assert np.all(ref.image[3] == 100.0)
