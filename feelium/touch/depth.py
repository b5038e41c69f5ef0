"""Relative shadow depth: the fraction of back-light lost against the reference.

Dividing by the reference makes the signal independent of the projector's
uneven (3:1 or worse) brightness. A pixel whose expected back-light is too dark
carries no information and a saturated pixel cannot show how much light it
lost, so both are masked to depth 0 instead of being divided through; the
result is finite and in [0, 1] for any input.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feelium.touch.buffers import Scratch


@dataclass
class MaskCounts:
    """Pixels masked in the last frame (working resolution), for health and tests."""

    dark: int = 0
    saturated: int = 0


def relative_depth(
    frame: np.ndarray,
    reference: np.ndarray,
    gain: float | np.ndarray,
    *,
    dark_level: float,
    saturation_level: float,
    counts: MaskCounts | None = None,
    signed: bool = False,
    scratch: Scratch | None = None,
) -> np.ndarray:
    """``clip(1 - frame / (gain * reference), 0, 1)`` where usable, 0 where masked.

    ``signed=True`` clips to [-1, 1] instead: smoothing must see the noise's
    negative half too, or clipping first would bias every smoothed pixel up
    (and the negative half is where the noise level can be measured).

    ``frame`` and ``reference`` are same-shape float arrays (the frame may
    already have the projected back-light divided out); ``gain`` is a number
    or an array that broadcasts (per-row gains). With ``scratch`` every array,
    the result included, is one of its buffers (valid until its next use);
    without, the result is a new array.
    """
    buf = Scratch() if scratch is None else scratch
    dtype = reference.dtype.type
    factor = dtype(gain) if np.isscalar(gain) else gain.astype(reference.dtype, copy=False)
    expected = np.multiply(reference, factor, out=buf.like("depth.expected", reference))
    dark = np.greater_equal(expected, dark_level, out=buf.like("depth.dark", reference, bool))
    np.logical_not(dark, out=dark)  # also catches NaN
    saturated = np.less(frame, saturation_level, out=buf.like("depth.saturated", reference, bool))
    np.logical_not(saturated, out=saturated)
    masked = np.logical_or(dark, saturated, out=buf.like("depth.masked", reference, bool))
    np.copyto(expected, dtype(1.0), where=masked)
    depth = np.divide(frame, expected, out=buf.get("depth.depth", expected.shape, np.result_type(frame, expected)))
    np.subtract(dtype(1.0), depth, out=depth)
    depth.clip(-1.0 if signed else 0.0, 1.0, out=depth)  # the method: np.clip less its dispatch
    np.copyto(depth, depth.dtype.type(0.0), where=masked)
    bad = np.isfinite(depth, out=buf.like("depth.bad", reference, bool))
    np.logical_not(bad, out=bad)
    np.copyto(depth, depth.dtype.type(0.0), where=bad)
    if counts is not None:
        counts.dark = int(np.count_nonzero(dark))
        only_saturated = np.logical_not(dark, out=bad)
        np.logical_and(only_saturated, saturated, out=only_saturated)
        counts.saturated = int(np.count_nonzero(only_saturated))
    return depth
