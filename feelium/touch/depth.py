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
) -> np.ndarray:
    """``clip(1 - frame / (gain * reference), 0, 1)`` where usable, 0 where masked.

    ``signed=True`` clips to [-1, 1] instead: smoothing must see the noise's
    negative half too, or clipping first would bias every smoothed pixel up
    (and the negative half is where the noise level can be measured).

    ``frame`` and ``reference`` are same-shape float arrays (the frame may
    already have the projected back-light divided out); ``gain`` is a number
    or an array that broadcasts (per-row gains).
    """
    dtype = reference.dtype.type
    expected = reference * (dtype(gain) if np.isscalar(gain) else gain.astype(reference.dtype, copy=False))
    dark = ~(expected >= dark_level)  # also catches NaN
    saturated = ~(frame < saturation_level)
    masked = dark | saturated
    np.copyto(expected, dtype(1.0), where=masked)
    depth = frame / expected
    np.subtract(dtype(1.0), depth, out=depth)
    np.clip(depth, -1.0 if signed else 0.0, 1.0, out=depth)
    depth[masked] = 0.0
    depth[~np.isfinite(depth)] = 0.0
    if counts is not None:
        counts.dark = int(np.count_nonzero(dark))
        counts.saturated = int(np.count_nonzero(saturated & ~dark))
    return depth
