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
leave a sharp-edged false shadow the size of the shadow mask (under a hover
held through a switch, that false shadow landed and fired). So on a
lighting step (the gain jumps) the change's map is taken whatever its
spread (``force``): the first frame of a lamp's 0.1 s ramp changes the shape
by less than the limit but already by enough to matter under a shadow. Then
the reference is re-seeded: the frame itself where nothing is shadowed, and
under shadows the old reference times the exposure's change plus the light
the room added around them (per tile ``frame = e * reference + r``: one
exposure factor fitted over the tiles, the room's smooth ``r`` interpolated
from the tiles around a shadow), because room light adds to the back-light
and varies smoothly.
"""

from __future__ import annotations

import cv2
import numpy as np

from feelium.touch.buffers import Scratch
from feelium.touch.median import median

TILE_PX = 16  # working pixels per coarse tile side at detect_scale 1 (a fixed part of the membrane: tile_px_for)
MIN_TILE_WEIGHT = 0.5  # share of a tile's pixels that must be usable for its mean to count
MIN_TILES = 8
FILL_SIGMA_TILES = 1.5  # tiles under a hand take the change of the good tiles within about this many tiles


def tile_px_for(detect_scale: float) -> int:
    """The tile's side in detection pixels when detection runs at ``detect_scale`` of the working resolution.

    Why: a tile is a part of the membrane, not a number of pixels. Its statistics rest on that: a hand covers less
    than half the tiles (the median's breakdown point), and a tile averages the same camera pixels' noise. Kept at
    16 detection pixels, the tiles at 0.5 were four times larger on the membrane and four times fewer: a lean-in
    hug growing by a fifth of the membrane in one frame then covered enough of them to read as a change of the
    room's light, and the re-seed ate the hug (tests/projector/test_exchanges.py, at 0.5)."""
    return max(2, int(round(TILE_PX * detect_scale)))


def tile_means(
    frame: np.ndarray, reference: np.ndarray, usable: np.ndarray, scratch: Scratch | None = None,
    tile_px: int = TILE_PX,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per coarse tile of ``tile_px`` pixels a side: the mean of frame and of reference over usable pixels, and the
    usable share of the tile.

    ``scratch`` holds the working-size temporaries (:mod:`feelium.touch.buffers`); the results are new arrays.
    Tiles with no usable pixel have means 0.
    """
    h, w = frame.shape
    size = (max(1, w // tile_px), max(1, h // tile_px))
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
        inv = np.where(share > 0.0, 1.0 / np.maximum(share, 1e-6), 0.0)
    return (num * inv).astype(np.float32), (den * inv).astype(np.float32), share


def illumination_change(
    frame: np.ndarray,
    reference: np.ndarray,
    gain: float,
    usable: np.ndarray,
    spread_limit: float,
    scratch: Scratch | None = None,
    *,
    force: bool = False,
    tile_px: int = TILE_PX,
) -> tuple[float, np.ndarray] | None:
    """How the light changed, ``(e, added)`` with ``frame / gain = e * reference + added``, if it changed shape.

    ``e`` is the exposure's share of the change (one factor), ``added`` (working size) the smooth light the room
    added on top of it.

    ``usable``: pixels neither masked (dark, saturated) nor under a shadow of the previous frame. The decision
    is on the tiles' ratios ``frame / (gain * reference)``: None when their median absolute deviation is within
    ``spread_limit`` of their median (the light kept its shape), unless ``force``: the caller already knows the
    light stepped (the exposure gain jumped) and needs the change's map whatever its shape, because the first
    frame of a lamp's ramp changes the shape by less than the limit and a single gain would still be wrong
    under shadows. Also None when too few tiles are usable to measure anything.

    The map is additive, not a ratio: room light adds to the back-light, so the light it adds is smooth across
    the membrane (a lamp, a person's soft shadow on it) while its ratio to the back-light follows the
    back-light's 4.5-7:1 falloff, and a ratio interpolated from around a bright spot overestimated it there
    (under a hover at the centre: a false shadow deeper than the hover's, which landed and fired).
    """
    mean_frame, mean_ref, share = tile_means(frame, reference, usable, scratch, tile_px)
    good = (share >= MIN_TILE_WEIGHT) & (mean_ref > 0.0)
    if np.count_nonzero(good) < MIN_TILES or not gain > 0.0:
        return None
    with np.errstate(invalid="ignore", divide="ignore"):
        values = mean_frame[good] / (np.float32(gain) * mean_ref[good])
    middle = median(values)
    spread = median(np.abs(values - middle))
    if not (np.isfinite(middle) and np.isfinite(spread) and middle > 0.0):
        return None
    if spread <= spread_limit * middle and not force:
        return None
    # frame = e * gain * reference + r per tile: exposure multiplies everything, room light adds. One e and the
    # smooth r are separable because the back-light (the reference) varies 4.5-7:1 across the tiles.
    x = mean_ref[good].astype(np.float64) * gain
    y = mean_frame[good].astype(np.float64)
    e, r0 = np.polyfit(x, y, 1)
    if not (np.isfinite(e) and np.isfinite(r0)):
        return None
    added = ((mean_frame - np.float32(e * gain) * mean_ref) * np.float32(1.0 / gain)).astype(np.float32)
    # Tiles without enough membrane (under a hand, masked) take the light added around them (room light is
    # smooth), not the membrane's median.
    added[~good] = _fill(added, good, r0 / gain)[~good]
    h, w = frame.shape
    return float(e), cv2.resize(added, (w, h), interpolation=cv2.INTER_LINEAR)


def _fill(ratio: np.ndarray, good: np.ndarray, default: float) -> np.ndarray:
    """Each tile's ratio estimated from the good tiles near it (a Gaussian-weighted mean, normalised convolution);
    ``default`` where no good tile is near."""
    weight = good.astype(np.float32)
    values = np.where(good, ratio, np.float32(0.0)).astype(np.float32)
    num = cv2.GaussianBlur(values, (0, 0), FILL_SIGMA_TILES, borderType=cv2.BORDER_REPLICATE)
    den = cv2.GaussianBlur(weight, (0, 0), FILL_SIGMA_TILES, borderType=cv2.BORDER_REPLICATE)
    return np.where(den > 1e-3, num / np.maximum(den, 1e-3), np.float32(default)).astype(np.float32)


def reseed(
    reference: np.ndarray, expected: np.ndarray, change: tuple[float, np.ndarray], shadow: np.ndarray | None
) -> np.ndarray:
    """The re-seeded reference: ``expected`` (frame over gain) outside shadows, ``e * reference + added`` under
    them (``change`` from :func:`illumination_change`)."""
    out = expected.astype(reference.dtype, copy=True)
    if shadow is not None and shadow.any():
        e, added = change
        np.copyto(out, reference * reference.dtype.type(e) + added, where=shadow)
    return out
