"""The sensing lift is its look-up table, byte for byte, however it is computed."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.projector.lift import SensingLift, lift_lut


@pytest.mark.parametrize("key", range(1, 256))
def test_every_floor_lifts_every_byte_as_its_table_does(key: int) -> None:
    lift = SensingLift(key / 255.0, 0.0)
    # Every byte value in every channel, in a canvas-sized contiguous image (the vectorised path) and in a view
    # with rows a few bytes long (the scalar path), lifted in place.
    canvas = np.resize(np.arange(256, dtype=np.uint8), (384, 512, 3))
    lifted = canvas.copy()
    lift.apply(lifted)
    assert np.array_equal(lifted, lift_lut(key / 255.0)[canvas])
    strided = np.resize(np.arange(256, dtype=np.uint8), (256, 7, 3))
    view = strided[:, :1]
    expected = lift_lut(key / 255.0)[view]
    lift.apply(view)
    assert np.array_equal(view, expected)
    assert np.array_equal(strided[:, 1:], np.resize(np.arange(256, dtype=np.uint8), (256, 7, 3))[:, 1:])  # untouched


def test_a_zero_floor_leaves_the_canvas_alone() -> None:
    canvas = np.resize(np.arange(256, dtype=np.uint8), (16, 16, 3))
    lifted = canvas.copy()
    SensingLift(0.0, 0.0).apply(lifted)
    assert np.array_equal(lifted, canvas)
