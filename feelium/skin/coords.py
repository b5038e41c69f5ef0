"""Camera pixel to skin ``(u, v)``: the one definition every part uses.

Camera coordinates put pixel *centres* on integers (OpenCV's convention, and
the touch pipeline's), so the ROI ``[x, y, w, h]`` covers ``x - 0.5 .. x + w - 0.5``.
``u`` runs 0 -> 1 from the left edge of the ROI's first column to the right
edge of its last, ``v`` 0 -> 1 from the top edge of its first row to the bottom
edge of its last (the camera's own axes: ``u`` right, ``v`` down as the rear
camera sees the membrane). The projector's skin canvas uses the same edges
(``u * width``), so a region, a touch and an answer mean the same spot.
"""

from __future__ import annotations

Roi = tuple[int, int, int, int]


def skin_uv(roi: Roi, x: float, y: float) -> tuple[float, float]:
    """Skin position of camera pixel ``(x, y)``; inside the ROI both lie in ``[0, 1)``."""
    rx, ry, rw, rh = roi
    return (x - rx + 0.5) / rw, (y - ry + 0.5) / rh


def inside_roi(roi: Roi, x: float, y: float) -> bool:
    """Whether camera pixel ``(x, y)`` lies on the ROI (its pixels' full extent, edges as :func:`skin_uv`)."""
    u, v = skin_uv(roi, x, y)
    return 0.0 <= u < 1.0 and 0.0 <= v < 1.0
