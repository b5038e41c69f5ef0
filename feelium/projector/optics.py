"""How finely the projector frame needs warping: the grid the skin canvas is remapped onto before scaling up.

The canvas (512x384 by default) is all the detail there is: a projector pixel finer than a canvas pixel only
interpolates between canvas pixels. With the board bench's stand-in calibration a projector pixel is 0.635
canvas pixels wide (the canvas spans ~806 of the projector's 1280 columns), so 2.5 projector pixels are
warped for each canvas pixel. The warp is therefore done on the coarsest of a few grids that still has a
sample for every canvas pixel along both axes (:func:`warp_scale`), and that grid is scaled up to projector
pixels by a bilinear resize, which costs a fraction of a remap per pixel.

What the skin shows decides whether the second interpolation matters: the membrane diffuses the projected
light (``[projector] diffusion_px`` = 0.7 camera px, ~1.1 projector px with the stand-in map). On text drawn
at canvas resolution the 2/3 grid differs from the full warp by 33.6 dB PSNR raw, 41.8 dB after that blur;
a 1/2 grid, which drops canvas detail there, by 29.9 and 36.6 dB (``tests/projector/test_optics.py`` holds
the tolerance; docs/performance.md the measurement).

The calibration map is smooth (``[projector.calibration] smooth_sigma_px``, and a lens's distortion varies
over tens of pixels), so it is sampled bilinearly at the coarse grid's points; a point whose neighbours
include one off the skin is off the skin.
"""

from __future__ import annotations

import cv2
import numpy as np

SCALES = ((1, 2), (2, 3), (1, 1))  # (num, den) coarse grids tried, coarsest first; num divides the tile sides
OFF_SKIN = -10.0  # a map value outside the canvas: the remap gives the border colour


def canvas_density(map_x: np.ndarray, map_y: np.ndarray) -> float:
    """Canvas pixels per projector pixel along the denser axis, the 95th percentile over the skin (NaN off it)."""
    step_x = np.hypot(np.diff(map_x, axis=1)[:-1], np.diff(map_y, axis=1)[:-1])
    step_y = np.hypot(np.diff(map_x, axis=0)[:, :-1], np.diff(map_y, axis=0)[:, :-1])
    steps = np.maximum(step_x, step_y)
    steps = steps[np.isfinite(steps)]
    return float(np.percentile(steps, 95)) if steps.size else 1.0


def warp_scale(density: float) -> tuple[int, int]:
    """The coarsest grid (num, den: num/den of the projector's pixels per axis) with a sample per canvas pixel."""
    for num, den in SCALES:
        if num / den >= density:
            return num, den
    return 1, 1


def fit_box(box: tuple[int, int, int, int], frame_size: tuple[int, int], den: int) -> tuple[int, int, int, int]:
    """``box`` grown to sides that are multiples of ``den`` (so the coarse grid has whole pixels), kept in the frame."""
    x0, y0, x1, y1 = box
    fw, fh = frame_size
    w, h = min(-(-(x1 - x0) // den) * den, fw // den * den), min(-(-(y1 - y0) // den) * den, fh // den * den)
    x0, y0 = min(x0, fw - w), min(y0, fh - h)
    return x0, y0, x0 + w, y0 + h


def coarse_maps(
    map_x: np.ndarray, map_y: np.ndarray, box: tuple[int, int, int, int], scale: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Fixed-point maps (``CV_16SC2``) of the coarse grid over ``box`` from the projector-sized float maps.

    Coarse pixel (j, i) is box pixel ((j + 0.5) den/num - 0.5, ...), as a bilinear resize by den/num reads it.
    """
    num, den = scale
    x0, y0, x1, y1 = box
    w, h = (x1 - x0) * num // den, (y1 - y0) * num // den
    fx = x0 + (np.arange(w) + 0.5) * (den / num) - 0.5
    fy = y0 + (np.arange(h) + 0.5) * (den / num) - 0.5
    sx, sy = _bilinear(map_x, fx, fy), _bilinear(map_y, fx, fy)
    off = ~(np.isfinite(sx) & np.isfinite(sy))
    sx[off] = OFF_SKIN
    sy[off] = OFF_SKIN
    return cv2.convertMaps(sx.astype(np.float32), sy.astype(np.float32), cv2.CV_16SC2)


def _bilinear(values: np.ndarray, fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
    """``values`` sampled at the grid of columns ``fx`` and rows ``fy`` (clamped to the array); NaN spreads."""
    h, w = values.shape
    fx, fy = np.clip(fx, 0.0, w - 1.0), np.clip(fy, 0.0, h - 1.0)
    ix, iy = np.minimum(fx.astype(np.int64), w - 2), np.minimum(fy.astype(np.int64), h - 2)
    ax, ay = (fx - ix)[None, :], (fy - iy)[:, None]
    v = values.astype(np.float64)
    top = v[iy][:, ix] * (1 - ax) + v[iy][:, ix + 1] * ax
    bottom = v[iy + 1][:, ix] * (1 - ax) + v[iy + 1][:, ix + 1] * ax
    return top * (1 - ay) + bottom * ay
