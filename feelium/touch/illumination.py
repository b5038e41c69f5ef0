"""Room-light changes: when the reference no longer describes the membrane everywhere, re-seed it.

Room light through the membrane adds to the projector's back-light; it does
not multiply it. A lamp switched on raises the dim corners of a 5:1 back-light
by a much larger factor than the bright centre, so the exposure gain (one
median ratio) cannot absorb it: half the membrane would look shadowed, half
brighter than it is, and the adaptive reference would freeze under the false
"shadow" for a minute. A hand changes part of the membrane, a switch, daylight
or a person walking past the lamp changes all of it, smoothly.

So every frame, before the exposure gain is adopted, frame over reference is
summarised per coarse tile (over usable pixels not under a shadow of the
previous frame; a tile of 16 x 16 working pixels averages the pixel noise down
by 16) and the *spread* of the tiles (median absolute deviation, relative to
their median, so exposure cancels) is compared with the darkening floor
(``noise_floor``): more than half the membrane off by that much means the light
has changed shape, while a hand, even a hand arriving in one frame as close and
large as a palm, covers less than half the tiles and cannot move the statistic
(its breakdown point is one half). The exposure gain's own lighting-step re-baseline
(:mod:`feelium.touch.reference`) scales the old reference under shadows by
one gain, which is right for exposure and wrong for added light: it would
leave a sharp-edged false shadow the size of the shadow mask. Then
the reference is re-seeded: the frame itself where nothing is shadowed, and
under shadows the old reference times the change measured around them (the
tile map, interpolated), because room light varies smoothly.
"""

from __future__ import annotations

import cv2
import numpy as np

from feelium.touch.buffers import Scratch

TILE_PX = 16  # working pixels per coarse tile side
MIN_TILE_WEIGHT = 0.5  # share of a tile's pixels that must be usable for its mean to count
MIN_TILES = 8


def tile_ratios(
    frame: np.ndarray, reference: np.ndarray, usable: np.ndarray, scratch: Scratch | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Per coarse tile: frame over reference summed over usable pixels, and the usable share of the tile.

    ``scratch`` holds the working-size temporaries (:mod:`feelium.touch.buffers`); the results are new arrays.
    """
    h, w = frame.shape
    size = (max(1, w // TILE_PX), max(1, h // TILE_PX))
    buf = Scratch() if scratch is None else scratch
    weight = buf.like("tiles.weight", usable, np.float32)
    np.copyto(weight, usable)
    dtype = np.result_type(frame, weight)
    weighted = np.multiply(frame, weight, out=buf.get("tiles.weighted", frame.shape, dtype))
    num = cv2.resize(weighted, size, interpolation=cv2.INTER_AREA)
    dtype = np.result_type(reference, weight)
    weighted = np.multiply(reference, weight, out=buf.get("tiles.weighted", frame.shape, dtype))
    den = cv2.resize(weighted, size, interpolation=cv2.INTER_AREA)
    share = cv2.resize(weight, size, interpolation=cv2.INTER_AREA)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(den > 0.0, num / np.maximum(den, 1e-6), 1.0).astype(np.float32)
    return ratio, share


def illumination_change(
    frame: np.ndarray,
    reference: np.ndarray,
    gain: float,
    usable: np.ndarray,
    spread_limit: float,
    scratch: Scratch | None = None,
) -> np.ndarray | None:
    """The smooth change of light (working size, frame over ``gain * reference``) if the membrane changed shape.

    ``usable``: pixels neither masked (dark, saturated) nor under a shadow of the previous frame.
    Returns None when the tiles' median absolute deviation is within ``spread_limit`` of their median (the
    light kept its shape).
    """
    ratio, share = tile_ratios(frame, reference, usable, scratch)
    good = share >= MIN_TILE_WEIGHT
    if np.count_nonzero(good) < MIN_TILES or not gain > 0.0:
        return None
    ratio *= np.float32(1.0 / gain)
    values = ratio[good]
    median = float(np.median(values))
    spread = float(np.median(np.abs(values - median)))
    if not (np.isfinite(median) and np.isfinite(spread)) or spread <= spread_limit * median:
        return None
    # Tiles without enough membrane (under a hand, masked) take the median change: room light is smooth.
    ratio[~good] = np.float32(median)
    h, w = frame.shape
    return cv2.resize(ratio, (w, h), interpolation=cv2.INTER_LINEAR)


def reseed(reference: np.ndarray, expected: np.ndarray, change: np.ndarray, shadow: np.ndarray | None) -> np.ndarray:
    """The re-seeded reference: ``expected`` (frame over gain) outside shadows, ``reference * change`` under them."""
    out = expected.astype(reference.dtype, copy=True)
    if shadow is not None and shadow.any():
        np.copyto(out, reference * change, where=shadow)
    return out
