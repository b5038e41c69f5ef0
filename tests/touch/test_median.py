"""The per-frame median (feelium.touch.median) is numpy's to the bit, NaN included."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from feelium.touch.median import median


@given(values=st.lists(st.floats(-1e6, 1e6, width=32), min_size=1, max_size=400))
def test_a_float32_median_is_numpys_to_the_bit(values: list[float]) -> None:
    array = np.array(values, np.float32)
    assert median(array) == float(np.median(array))


@given(values=st.lists(st.floats(-1e300, 1e300), min_size=1, max_size=400))
def test_a_float64_median_is_numpys_to_the_bit(values: list[float]) -> None:
    array = np.array(values, np.float64)
    assert median(array) == float(np.median(array))


@given(
    values=st.lists(st.floats(-1e6, 1e6, width=32), min_size=0, max_size=50),
    at=st.integers(0, 50),
)
def test_any_nan_makes_the_median_nan_as_numpys(values: list[float], at: int) -> None:
    values.insert(min(at, len(values)), float("nan"))
    array = np.array(values, np.float32)
    assert math.isnan(median(array)) and math.isnan(float(np.median(array)))
