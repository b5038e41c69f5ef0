"""Where a Gaussian blur of part of a membrane image equals, bit for bit, the blur of the whole image.

Both users blur an image of which only part matters (the projected light, read
only over the touch ROI) or only part is nonzero (the prediction's spread, zero
wherever the projector showed the same light all exposure long). Blurring a
window that holds that part and the kernel's reach around it gives the same
values there; and OpenCV's row filter runs in SIMD blocks from each row's start
with a scalar tail, so a window that starts on a block and is whole blocks wide
(or ends at the image's edge) also sums every pixel in the same order: the same
bits, not only the same value to a rounding. Shared by :mod:`feelium.projector`
and :mod:`feelium.touch`, which may not import each other.
"""

from __future__ import annotations

import math

SIMD_PX = 16  # float pixels per SIMD block of OpenCV's row filters (AVX-512: 16; AVX2: 8; NEON: 4), or a multiple

Window = tuple[slice, slice]  # (rows, columns) of the image


def gaussian_radius(sigma: float) -> int:
    """How far (pixels) ``cv2.GaussianBlur(..., (0, 0), sigma)`` reads around a float image's pixel: OpenCV sizes the
    kernel ``round(8 * sigma + 1) | 1`` for float images. Beyond it a window's border handling changes nothing."""
    return (int(math.floor(8.0 * sigma + 1.5)) | 1) // 2 if sigma > 0 else 0


def blur_window(size: tuple[int, int], box: tuple[int, int, int, int], sigma: float) -> Window:
    """The window of a ``size`` = (width, height) image to blur by ``sigma`` so that the box [x, y, w, h] comes out
    as in the whole image's blur: the box, the kernel's reach around it, widened to whole SIMD blocks."""
    width, height = size
    bx, by, bw, bh = box
    reach = gaussian_radius(sigma)
    x0, y0 = (max(0, bx - reach) // SIMD_PX) * SIMD_PX, max(0, by - reach)
    x1 = min(width, x0 + -(-(bx + bw + reach - x0) // SIMD_PX) * SIMD_PX)
    y1 = min(height, by + bh + reach)
    return slice(y0, y1), slice(x0, x1)
