"""Relative depth: right where it can be computed, masked where it cannot, never NaN or inf."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from feelium.touch.depth import MaskCounts, relative_depth

arrays = hnp.arrays(np.float32, (6, 7), elements=st.floats(0.0, 255.0, width=32))


def test_depth_is_the_fraction_of_light_lost():
    ref = np.full((4, 4), 200.0, np.float32)
    frame = np.full((4, 4), 50.0, np.float32)
    depth = relative_depth(frame, ref, 1.0, dark_level=10, saturation_level=250)
    np.testing.assert_allclose(depth, 0.75, rtol=1e-6)


def test_gain_scales_the_expected_light():
    ref = np.full((3, 3), 100.0, np.float32)
    frame = np.full((3, 3), 150.0, np.float32)
    depth = relative_depth(frame, ref, 2.0, dark_level=10, saturation_level=250)
    np.testing.assert_allclose(depth, 0.25, rtol=1e-6)


def test_independent_of_uneven_backlight():
    ref = np.linspace(30, 220, 64, dtype=np.float32).reshape(8, 8)
    depth = relative_depth(ref * 0.4, ref, 1.0, dark_level=10, saturation_level=250)
    np.testing.assert_allclose(depth, 0.6, rtol=1e-5)


def test_dark_and_saturated_pixels_are_masked_and_counted():
    ref = np.array([[5.0, 100.0, 100.0]], np.float32)
    frame = np.array([[0.0, 255.0, 50.0]], np.float32)
    counts = MaskCounts()
    depth = relative_depth(frame, ref, 1.0, dark_level=10, saturation_level=250, counts=counts)
    assert depth.tolist() == [[0.0, 0.0, 0.5]]
    assert (counts.dark, counts.saturated) == (1, 1)


@given(arrays, arrays, st.floats(0.0, 1e3))
def test_finite_and_bounded_for_any_input(frame, ref, gain):
    depth = relative_depth(frame, ref, gain, dark_level=1.0, saturation_level=250)
    assert np.all(np.isfinite(depth))
    assert depth.min() >= 0.0 and depth.max() <= 1.0


def test_reference_of_zeros_gives_zero_depth():
    depth = relative_depth(np.zeros((5, 5), np.float32), np.zeros((5, 5), np.float32), 1.0, dark_level=1, saturation_level=250)
    assert not depth.any()


def test_nan_in_reference_is_masked():
    ref = np.array([[np.nan, np.inf, 100.0]], np.float32)
    depth = relative_depth(np.full((1, 3), 50.0, np.float32), ref, 1.0, dark_level=10, saturation_level=250)
    assert np.all(np.isfinite(depth))
    assert depth[0, 2] == 0.5
