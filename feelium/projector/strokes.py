"""A drawing round's strokes, drawn once into a layer that is laid over each canvas.

A round holds up to 64 strokes of 256 points (``feelium.interactions.engine``),
and the skin shows them until the round ends. Drawing every stroke on every
frame made a frame's cost grow with the drawing (the 30-minute soak: 4.5 ->
8.1 ms a frame); here each point is drawn once, and a frame only lays the layer
over the canvas (two uint8 operations on the strokes' bounding box).

The layer is premultiplied BGRA: OpenCV's anti-aliased drawing of colour ``C``
with coverage ``c`` onto a pixel ``P`` gives ``P + (C - P) c``, which on a
premultiplied layer that starts transparent is exactly Porter-Duff "over", so
``layer + canvas (1 - alpha)`` is the stroke drawn onto the canvas, up to the
8-bit steps rounding apart on anti-aliased rims (tests/projector/test_strokes.py:
at most 9 grey levels measured where 64 strokes overlap, 1-3 on the ~4 % of
drawn pixels that differ at all). Each stroke is a
wide halo under a thin white core, both over the whole stroke; so the newest
stroke, the one still growing, keeps its halo and core as two coverage masks to
which only new segments are added, exactly as the whole polyline would draw
them (:func:`draw_segments`; adding a segment's halo straight into the layer
would cover the core drawn before it). It is merged into the frozen layer when a
newer stroke starts. A stroke that leaves the skin, a round that changes, or an
older stroke that grows again (two fingers drawing at once) redraws the layer
from the strokes once.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass

import math

import cv2
import numpy as np

from feelium.interactions.answers import Answer

STROKE_BGR = (255, 255, 90)
CORE_BGR = (255, 255, 255)

_XY_SHIFT = 16  # OpenCV's drawing.cpp fixed point
_XY_ONE = 1 << _XY_SHIFT
_INV_XY_ONE = 1.0 / _XY_ONE
_DBL_EPSILON = 2.220446049250313e-16

Point = tuple[float, float]
Box = tuple[int, int, int, int]  # x0, y0, x1, y1 (exclusive), canvas pixels


def stroke_key(answer: Answer) -> Hashable:
    """A stroke's identity: the engine's round and stroke numbers; else its start time and first point."""
    detail = answer.detail
    if "stroke" in detail:
        return (detail.get("round"), detail["stroke"])
    points = detail.get("points", ())
    return (None, answer.t0, points[0] if points else None)


def widths(canvas_width: int) -> tuple[int, int, int]:
    """(halo thickness, core thickness, dot radius) of a stroke on a canvas this wide."""
    return max(4, canvas_width // 70), max(1, canvas_width // 250), max(3, canvas_width // 90)


def polyline(points: Sequence[Point], width: int, height: int) -> np.ndarray:
    """Canvas pixel vertices (int32, OpenCV's polyline shape) of u, v points."""
    return np.array([[u * width, v * height] for u, v in points], np.int32).reshape(-1, 1, 2)


def draw_segments(img: np.ndarray, px: Sequence[tuple[int, int]], first: bool, color: int, thickness: int) -> None:
    """The segments ``px[0] -> px[1] -> ...`` exactly as ``cv2.polylines(..., cv2.LINE_AA)`` draws them within a
    polyline that starts at ``px[0]`` (``first``) or earlier (the tail of a stroke drawn before).

    OpenCV draws a thick polyline segment by segment: a convex quadrilateral, a round cap at the segment's end, and at
    the first segment's start too (``ThickLine`` in imgproc/src/drawing.cpp). Drawing a new tail as a polyline of its
    own would add a cap at its first point, where the previous segment's end cap already is, and darken that cap's
    anti-aliased rim a second time; so the same quadrilaterals and caps are drawn here, with OpenCV's own
    fixed-point arithmetic (16 fractional bits), and a polyline drawn in pieces equals the polyline drawn at once.
    """
    for i in range(1, len(px)):
        (x0, y0), (x1, y1) = px[i - 1], px[i]
        if thickness <= 1:
            cv2.line(img, (x0, y0), (x1, y1), color, 1, cv2.LINE_AA)
            continue
        sx0, sy0, sx1, sy1 = x0 << _XY_SHIFT, y0 << _XY_SHIFT, x1 << _XY_SHIFT, y1 << _XY_SHIFT
        dx, dy = (sx0 - sx1) * _INV_XY_ONE, (sy1 - sy0) * _INV_XY_ONE
        r = dx * dx + dy * dy
        half = thickness << (_XY_SHIFT - 1)
        if abs(r) > _DBL_EPSILON:
            r = (half + (thickness & 1) * _XY_ONE * 0.5) / math.sqrt(r)
            ox, oy = round(dy * r), round(dx * r)  # cvRound: half to even, as Python's round
            quad = np.array([[sx0 + ox, sy0 + oy], [sx0 - ox, sy0 - oy], [sx1 - ox, sy1 - oy], [sx1 + ox, sy1 + oy]], np.int32)
            cv2.fillConvexPoly(img, quad, color, cv2.LINE_AA, _XY_SHIFT)
        caps = ((sx0, sy0), (sx1, sy1)) if first and i == 1 else ((sx1, sy1),)
        for centre in caps:
            cv2.ellipse(img, centre, (half, half), 0, 0, 360, color, -1, cv2.LINE_AA, _XY_SHIFT)


def draw_points(img: np.ndarray, points: Sequence[Point], halo: tuple[int, ...], core: tuple[int, ...] | None) -> None:
    """One stroke as ``layers.draw_stroke`` draws it: a dot for one point, else the halo then the core
    (``core`` None: the halo only)."""
    h, w = img.shape[:2]
    halo_t, core_t, dot_r = widths(w)
    if len(points) == 1:
        u, v = points[0]
        cv2.circle(img, (int(u * w), int(v * h)), dot_r, halo, -1, cv2.LINE_AA)
        return
    if len(points) >= 2:
        line = polyline(points, w, h)
        cv2.polylines(img, [line], False, halo, halo_t, cv2.LINE_AA)
        if core is not None:
            cv2.polylines(img, [line], False, core, core_t, cv2.LINE_AA)


def _box_of(points: Sequence[Point], width: int, height: int) -> Box:
    """Canvas pixels a stroke through ``points`` can touch (its halo, dot and anti-aliased rim), clipped."""
    pad = max(widths(width)[0] // 2, widths(width)[2]) + 3
    xs = [int(u * width) for u, _ in points]
    ys = [int(v * height) for _, v in points]
    return (max(0, min(xs) - pad), max(0, min(ys) - pad), min(width, max(xs) + pad + 1), min(height, max(ys) + pad + 1))


def _union(a: Box | None, b: Box | None) -> Box | None:
    if a is None or b is None:
        return a or b
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


@dataclass
class _Drawn:
    """What the layer holds of one stroke: how many points, and the last of them (to tell growth from change)."""

    count: int
    last: Point


class StrokeLayer:
    """The strokes of the answers handed in, kept drawn between frames; one caller at a time."""

    def __init__(self, width: int, height: int) -> None:
        self.size = (width, height)
        self.version = 0  # changes whenever what the layer shows changes
        self._seen: list[Answer] = []  # the answers the layer was last brought to
        self._drawn: dict[Hashable, _Drawn] = {}
        self._order: list[Hashable] = []  # strokes in the layer, in drawing order; the last one is live
        self._arrays: _Arrays | None = None

    def update(self, strokes: Sequence[Answer]) -> int:
        """Bring the layer to ``strokes`` (stroke answers, in drawing order) and return its version."""
        strokes = [a for a in strokes if a.detail.get("points")]  # nothing to draw, as layers.draw_stroke
        if len(strokes) == len(self._seen) and all(a is b for a, b in zip(strokes, self._seen)):
            return self.version  # the very answers of last time (the engine replaces only a growing stroke's)
        seen = {id(a) for a in self._seen}  # answers met last time hold what was drawn of them then
        self._seen = strokes
        keys = [stroke_key(a) for a in strokes]
        if not strokes:
            if self._order:
                self._drop()
            return self.version
        points = [tuple(a.detail.get("points", ())) for a in strokes]
        same = [id(a) in seen or self._unchanged(k, p) for a, k, p in zip(strokes, keys, points)]
        if keys == self._order and all(same):
            return self.version
        frozen_same = keys[: len(self._order)] == self._order and all(same[: len(self._order) - 1])
        if self._arrays is None or not self._order or not frozen_same or len(keys) > len(self._order) + 1:
            self._rebuild(keys, points)
        else:
            if len(keys) == len(self._order) + 1:  # a newer stroke started: the live one joins the frozen layer
                live = self._order[-1]
                self._grow(live, points[len(self._order) - 1])
                self._arrays.freeze()
                self._order.append(keys[-1])
            self._grow(keys[-1], points[-1])
        self.version += 1
        return self.version

    @property
    def keys(self) -> tuple[Hashable, ...]:
        """The strokes the layer holds, in drawing order."""
        return tuple(self._order)

    def compose(self, canvas: np.ndarray) -> None:
        """Lay the strokes over ``canvas`` (BGR uint8, canvas-sized) in place."""
        if self._arrays is not None and self._order:
            self._arrays.compose(canvas)

    # ---- internals ---------------------------------------------------------------------------

    def _unchanged(self, key: Hashable, points: tuple[Point, ...]) -> bool:
        drawn = self._drawn.get(key)
        return drawn is not None and len(points) == drawn.count and (not points or points[-1] == drawn.last)

    def _grow(self, key: Hashable, points: tuple[Point, ...]) -> None:
        """Add ``points``' new segments to the live stroke's masks (the whole stroke again if it changed otherwise,
        or when its single dot becomes a line, which is drawn without the dot)."""
        assert self._arrays is not None
        if self._unchanged(key, points):
            return
        drawn = self._drawn.get(key)
        if drawn is not None and drawn.count >= 2 and len(points) > drawn.count and points[drawn.count - 1] == drawn.last:
            self._arrays.add_live(points, start=drawn.count)
        else:
            self._arrays.add_live(points, start=0)
        if points:
            self._drawn[key] = _Drawn(len(points), points[-1])

    def _rebuild(self, keys: list[Hashable], points: list[tuple[Point, ...]]) -> None:
        """Every stroke drawn again: the older ones straight into the frozen layer, the newest as the live one."""
        if self._arrays is None:
            self._arrays = _Arrays(*self.size)
        else:
            self._arrays.clear()
        self._drawn = {}
        for key, pts in zip(keys[:-1], points[:-1]):
            self._arrays.add_frozen(pts)
            if pts:
                self._drawn[key] = _Drawn(len(pts), pts[-1])
        self._order = list(keys)
        self._grow(keys[-1], points[-1])

    def _drop(self) -> None:
        """The round ended or its strokes left the skin: free the layer (2.4 MB)."""
        self._arrays = None
        self._seen = []
        self._drawn = {}
        self._order = []
        self.version += 1


class _Arrays:
    """The layer's pixels: the frozen strokes (premultiplied BGRA), the live stroke's halo and core coverage, and
    their composite as the two operands of the per-frame blend (premultiplied BGR, 255 - alpha in three channels)."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.frozen = np.zeros((height, width, 4), np.uint8)
        self.halo = np.zeros((height, width), np.uint8)
        self.core = np.zeros((height, width), np.uint8)
        self.premul = np.zeros((height, width, 3), np.uint8)
        self.clear_alpha = np.full((height, width, 3), 255, np.uint8)
        self.box: Box | None = None  # everything drawn
        self.live_box: Box | None = None

    def clear(self) -> None:
        for array in (self.frozen, self.halo, self.core, self.premul):
            array.fill(0)
        self.clear_alpha.fill(255)
        self.box = self.live_box = None

    def add_frozen(self, points: Sequence[Point]) -> None:
        """Draw a whole stroke over the frozen layer (and refresh the composite there)."""
        if not points:
            return
        draw_points(self.frozen, points, STROKE_BGR + (255,), CORE_BGR + (255,))
        box = _box_of(points, self.width, self.height)
        self.box = _union(self.box, box)
        self._refresh(box)

    def add_live(self, points: Sequence[Point], start: int) -> None:
        """Draw the live stroke ``points`` from segment ``start`` on (0: the whole stroke, anew) into its masks and
        refresh the composite where they changed."""
        fresh = start == 0
        if fresh and self.live_box is not None:
            x0, y0, x1, y1 = self.live_box
            self.halo[y0:y1, x0:x1] = 0
            self.core[y0:y1, x0:x1] = 0
            dirty: Box | None = self.live_box
            self.live_box = None
        else:
            dirty = None
        if points:
            halo_t, core_t, _ = widths(self.width)
            if len(points) == 1:
                draw_points(self.halo, points, (255,), None)
            else:
                tail = points[max(start - 1, 0) :]  # from the last point drawn: only new segments
                px = [(int(x), int(y)) for x, y in polyline(tail, self.width, self.height).reshape(-1, 2)]
                draw_segments(self.halo, px, start == 0, 255, halo_t)
                draw_segments(self.core, px, start == 0, 255, core_t)
            box = _box_of(points[max(start - 1, 0) :], self.width, self.height)
            self.live_box = _union(self.live_box, box)
            self.box = _union(self.box, box)
            dirty = _union(dirty, box)
        if dirty is not None:
            self._refresh(dirty)

    def freeze(self) -> None:
        """Merge the live stroke into the frozen layer (the composite already shows it) and empty its masks."""
        if self.live_box is None:
            return
        x0, y0, x1, y1 = self.live_box
        self.frozen[y0:y1, x0:x1, :3] = self.premul[y0:y1, x0:x1]
        self.frozen[y0:y1, x0:x1, 3] = 255 - self.clear_alpha[y0:y1, x0:x1, 0]
        self.halo[y0:y1, x0:x1] = 0
        self.core[y0:y1, x0:x1] = 0
        self.live_box = None

    def _refresh(self, box: Box) -> None:
        """The composite in ``box``: live core over live halo over the frozen layer."""
        x0, y0, x1, y1 = box
        if x0 >= x1 or y0 >= y1:
            return
        base = self.frozen[y0:y1, x0:x1].astype(np.float32)
        halo = self.halo[y0:y1, x0:x1].astype(np.float32)[:, :, None] * np.float32(1 / 255)
        core = self.core[y0:y1, x0:x1].astype(np.float32)[:, :, None] * np.float32(1 / 255)
        rgb = base[:, :, :3] * (1 - halo) + np.float32(STROKE_BGR) * halo
        alpha = base[:, :, 3:] * (1 - halo) + 255 * halo
        rgb = rgb * (1 - core) + np.float32(CORE_BGR) * core
        alpha = alpha * (1 - core) + 255 * core
        self.premul[y0:y1, x0:x1] = np.clip(np.rint(rgb), 0, 255).astype(np.uint8)
        self.clear_alpha[y0:y1, x0:x1] = (255 - np.clip(np.rint(alpha), 0, 255).astype(np.uint8))

    def compose(self, canvas: np.ndarray) -> None:
        """canvas = canvas (255 - alpha) / 255 + premultiplied colour, on the drawn box: two uint8 passes."""
        if self.box is None:
            return
        x0, y0, x1, y1 = self.box
        crop = canvas[y0:y1, x0:x1]
        kept = cv2.multiply(crop, self.clear_alpha[y0:y1, x0:x1], scale=1 / 255)
        cv2.add(kept, self.premul[y0:y1, x0:x1], dst=crop)
