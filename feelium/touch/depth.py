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
    factor = reference.dtype.type(gain) if np.isscalar(gain) else gain.astype(reference.dtype, copy=False)
    expected = np.multiply(reference, factor, out=buf.like("depth.expected", reference))
    return depth_against(
        frame, expected, dark_level=dark_level, saturation_level=saturation_level, counts=counts, signed=signed,
        scratch=buf,
    )  # fmt: skip


def depth_against(
    frame: np.ndarray,
    expected: np.ndarray,
    *,
    dark_level: float,
    saturation_level: float,
    counts: MaskCounts | None = None,
    signed: bool = False,
    scratch: Scratch | None = None,
) -> np.ndarray:
    """:func:`relative_depth` against ``expected`` (the reference times its gain, already made; left unchanged), to
    the bit.

    Why: the pipeline makes the reference times its gain once a frame and reads it four times (the depth, the
    spread's bound, the share's lesson, the fine pass), and the masks are built in fewer passes (masked pixels are
    divided by whatever they hold, then zeroed with the non-finite ones in one pass): on the Pi a numpy call on
    these small images is mostly its per-call cost (issue 16)."""
    buf = Scratch() if scratch is None else scratch
    usable = np.greater_equal(expected, dark_level, out=buf.like("depth.usable", expected, bool))  # NaN: not usable
    lit = int(np.count_nonzero(usable)) if counts is not None else 0
    unsaturated = np.less(frame, saturation_level, out=buf.like("depth.unsaturated", expected, bool))
    usable &= unsaturated
    if counts is not None:
        counts.dark = usable.size - lit
        counts.saturated = lit - int(np.count_nonzero(usable))
    masked = np.logical_not(usable, out=unsaturated)
    depth = buf.get("depth.depth", expected.shape, np.result_type(frame, expected))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # masked pixels (0, NaN, tiny): zeroed below
        np.divide(frame, expected, out=depth)  # whole: a ufunc's where= runs a loop several times slower
    np.subtract(depth.dtype.type(1.0), depth, out=depth)
    depth.clip(-1.0 if signed else 0.0, 1.0, out=depth)  # the method: np.clip less its dispatch
    bad = np.isnan(depth, out=usable)  # the clip took infinities to the bounds: only NaN is left not finite
    bad |= masked
    np.copyto(depth, depth.dtype.type(0.0), where=bad)
    return depth
