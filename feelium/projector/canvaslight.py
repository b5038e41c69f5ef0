"""Predicting the back-light the rear camera sees from the projector's skin canvas, not its warped frame.

The renderer carries the skin canvas to projector pixels through the
calibration, and the light at a camera pixel comes from the projector pixel
the calibration says lights it; composed, the light at a camera pixel is the
canvas at that pixel's canvas coordinate. That camera -> canvas map is fixed,
so it is built once, through the renderer's own maps (the calibration's fitted
inverse, then :func:`feelium.projector.renderer.canvas_map`, with the daemon's
face model when it has one), and each frame is then a look-up table over the
small grey canvas (gamma, black level: light is linear, so it is averaged as
light), an area reduction to about one canvas pixel per camera pixel, one remap
and the diffusion blur. Per frame that is about a third of the time of predicting from the
1280x720 frame (:class:`feelium.projector.backlight.BacklightPredictor`, which it
matches within the projector's pixel grid's blur: docs/touch.md), and what a
prediction needs to keep is a 512x384 grey canvas instead of a 2.7 MB frame.

Camera pixels that see projector pixels off the canvas (the renderer draws its
constant border colour there) get that colour's light; camera pixels the
calibration does not cover get 1.0 (no correction), as before, and a band around the patch is lit with
the border's light before the blur (a camera pixel at the edge sees a little of the dark border).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from feelium.projector.avatar import BACKGROUND_BGR
from feelium.projector.config import ProjectorConfig
from feelium.projector.renderer import CANVAS_MAP_BAND_POINTS, canvas_map
from feelium.skin.blurwindow import blur_window
from feelium.skin.face import FaceModel
from feelium.skin.projector_map import ProjectorMap, sample

RECENT_CANVASES = 3  # canvases whose light window() keeps: the frames one camera exposure mixes, and the next
_OFF = -10.0  # a map position no bilinear tap reaches: the remap's border value (the projector's border light)


def light_table(config: ProjectorConfig, calibration: ProjectorMap) -> np.ndarray:
    """(256,) float32: the light of each projector grey level relative to the flat grey the touch reference saw.

    Measured by the calibration when it could, else the configured black level and gamma.
    """
    black = calibration.black_level if calibration.black_level is not None else config.black_level
    gamma = calibration.gamma if calibration.gamma is not None else config.gamma
    levels = np.arange(256, dtype=np.float64) / 255.0
    light = black + (1.0 - black) * levels**gamma
    flat = black + (1.0 - black) * config.flat_level**gamma
    return (light / flat).astype(np.float32)


def area_sigma(average_of: int) -> float:
    """The blur (sigma, in pixels of the coarse grid) that stands in for averaging ``average_of`` x ``average_of``
    point samples of a finer grid into each coarse pixel; 0 for 1.

    Why: the touch pipeline's detection at ``detect_scale`` 0.5 used to read the working resolution's light
    area-averaged down, and its accuracy was measured so; predicted on the coarse grid directly, each value is a
    point sample, sharper than that mean at a face's edges. The mean of ``n`` samples spaced ``1/n`` apart along an
    axis spreads the light by a variance of ``(1 - 1/n**2) / 12`` coarse pixels squared (n = 2: sigma 0.25). Measured
    on a talking face (tests/projector/test_canvaslight.py), against the working light area-averaged: mean absolute
    difference 0.0015 -> 0.0010, 99th percentile 0.021 -> 0.013 with it; a hand-tuned 0.3 did a little better,
    0.35 worse."""
    n = max(int(average_of), 1)
    return float(np.sqrt((1.0 - 1.0 / (n * n)) / 12.0))


def border_grey() -> int:
    """The grey level of the colour the renderer fills the projector frame with off the canvas (BGR -> grey)."""
    border = np.array([[[int(c * 0.5) for c in BACKGROUND_BGR]]], np.uint8)
    return int(cv2.cvtColor(border, cv2.COLOR_BGR2GRAY)[0, 0])


class CanvasLightPredictor:
    """Grey skin canvas in, per-camera-pixel back-light gain (float32, ~1.0 = flat) out."""

    def __init__(
        self,
        config: ProjectorConfig,
        calibration: ProjectorMap,
        frame_size: tuple[int, int] | None = None,
        face: FaceModel | None = None,
        box: tuple[int, int, int, int] | None = None,
        *,
        average_of: int = 1,
        finer: CanvasLightPredictor | None = None,
    ) -> None:
        """``frame_size``: (width, height) of the touch pipeline's frames (default the calibration's camera size);
        ``face``: the face model the projector's renderer was given (its canvas then spans the face's u, v);
        ``box``: [x, y, w, h] of the frame the light is wanted for (the touch pipeline's ROI; default the whole
        frame). The light is then predicted only there, plus the diffusion blur's reach around it, and equals the
        whole frame's light cut to the box: the pipeline reads nothing else, and the ROI is ~64 % of the frame.
        ``average_of``: each value stands for the mean of ``average_of`` x ``average_of`` values of a finer grid
        (the touch pipeline's working grid, when it detects on a coarser one): :func:`area_sigma`. ``finer``: the
        predictor of that finer grid (the same config, calibration and face), whose :meth:`window` then reads the
        canvas light this one reduced on the way (see :meth:`_canvas_light`)."""
        self._finer = finer
        cw, ch = calibration.camera_size
        fw, fh = frame_size if frame_size is not None else (cw, ch)
        self.canvas_size = (config.canvas_width, config.canvas_height)
        self.frame_size = (fw, fh)
        # Which projector pixel each frame pixel sees (the calibration, at the frame size) ...
        proj_x, proj_y = calibration.proj_x, calibration.proj_y
        if (fw, fh) != (cw, ch):
            proj_x = cv2.resize(proj_x, (fw, fh), interpolation=cv2.INTER_LINEAR)
            proj_y = cv2.resize(proj_y, (fw, fh), interpolation=cv2.INTER_LINEAR)
        self._uncovered = ~(np.isfinite(proj_x) & np.isfinite(proj_y))
        # ... and which canvas point the renderer drew there: the very maps the renderer warps with.
        inv_x, inv_y = calibration.projector_to_camera()
        cam_x, cam_y, drawn = _renderer_camera_points(inv_x, inv_y, proj_x, proj_y, self._uncovered)
        map_x, map_y = canvas_map(cam_x, cam_y, calibration, self.canvas_size, face)
        off = ~(drawn & np.isfinite(map_x) & np.isfinite(map_y))
        # The canvas is reduced (area average of the light) to about one canvas pixel per camera pixel first:
        # sampling a finer canvas would alias at the face's edges, as the old predictor's 2x area reduction avoided.
        self.reduce = _reduction(map_x, map_y, off | self._uncovered)
        rw, rh = -(-self.canvas_size[0] // self.reduce), -(-self.canvas_size[1] // self.reduce)
        self._reduced_size = (rw, rh)
        map_x = np.where(off, _OFF, (map_x + 0.5) / self.reduce - 0.5).astype(np.float32)
        map_y = np.where(off, _OFF, (map_y + 0.5) / self.reduce - 0.5).astype(np.float32)
        self._map1, self._map2 = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
        self._lut = light_table(config, calibration)
        self._border = float(self._lut[border_grey()])
        # Canvas pixels no projector pixel reads are not on the skin: the projector shows its border there, and
        # a camera pixel at the patch's edge sees a little of it through the blur.
        undrawn = ~_drawn_canvas(inv_x, inv_y, calibration, self.canvas_size, face)
        self._undrawn = np.flatnonzero(undrawn) if undrawn.any() else None
        # The old predictor sampled the projector's own pixel grid: one projector pixel (a box), its 2x area
        # reduction and a bilinear look-up on that reduced grid blur by a variance of (1/12 + 4/12 + 4/6) projector
        # pixels squared. The canvas has no such grid, so that blur is added to the membrane's diffusion: the
        # prediction stays the old one's (docs/touch.md: against the simulator's light it is then as close).
        grid_px = 1.0 / _scale(proj_x, proj_y, self._uncovered)  # one projector pixel, in frame pixels
        self.diffusion_px = float(
            np.hypot(np.hypot(config.diffusion_px * fw / cw, grid_px * np.sqrt(13.0 / 12.0)), area_sigma(average_of))
        )
        # The projector's light beyond the patch is its border (or nothing), not the flat grey: a camera pixel at the
        # patch's edge sees some of it through the diffusion, so a band around the patch is lit with the border's
        # light and blurred with it; only what the calibration does not cover gets 1.0, after the blur.
        lit = ~self._uncovered
        if self.diffusion_px > 0:
            radius = max(1, int(np.ceil(3.0 * self.diffusion_px)))
            disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
            lit = cv2.dilate(lit.astype(np.uint8), disc).astype(bool)
        self._dark = ~lit
        weight = lit.astype(np.float32)
        blurred = cv2.GaussianBlur(weight, (0, 0), self.diffusion_px) if self.diffusion_px > 0 else weight
        self._lit_blur = np.maximum(blurred, 1e-3)
        # Everything above is per frame pixel; the light is computed only over the box and, when it is blurred,
        # the blur's reach around it (:mod:`feelium.skin.blurwindow`): inside the box, the whole frame's bits.
        bx, by, bw, bh = box if box is not None else (0, 0, fw, fh)
        if bw <= 0 or bh <= 0 or bx < 0 or by < 0 or bx + bw > fw or by + bh > fh:
            raise ValueError(f"box {box} does not fit the {fw}x{fh} frame")
        self.box = (int(bx), int(by), int(bw), int(bh))
        inside = (slice(by, by + bh), slice(bx, bx + bw))
        window = blur_window((fw, fh), self.box, self.diffusion_px) if self.diffusion_px > 0 else inside
        y0, x0 = window[0].start, window[1].start
        self._inner = (slice(by - y0, by - y0 + bh), slice(bx - x0, bx - x0 + bw))  # the box within the window
        self._map1, self._map2 = self._map1[window].copy(), self._map2[window].copy()
        self._dark = self._dark[window].copy()
        self._lit_blur = self._lit_blur[inside].copy()
        self._uncovered = self._uncovered[inside].copy()
        # The per-frame intermediates of :meth:`gain`, allocated once (sizes are fixed at construction).
        rw, rh = self._reduced_size
        self._lut_out = np.empty((self.canvas_size[1], self.canvas_size[0]), np.float32)
        self._reduced = np.empty((rh, rw), np.float32)
        self._seen = np.empty(self._map2.shape, np.float32)
        self._blurred = np.empty(self._map2.shape, np.float32)
        self._recent: list[tuple[np.ndarray, np.ndarray]] = []  # (canvas, its light) of the last windows' canvases
        self._mix = np.empty(0, np.float32)  # the last exposure's mixed canvas light (window_of_mix)
        self._mix_key: list[tuple[np.ndarray, float]] | None = None  # the parts it was mixed from

    def gain(self, canvas_grey: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """(h, w) float32 gain over the box (the whole frame by default) for a grey (uint8) skin canvas.

        ``out`` (box size, float32): write the gain there (the caller recycles the arrays of frames it no longer
        needs). Every intermediate is one of the predictor's own buffers: the daemon maps allocations from 128 KB
        (``[daemon] malloc_mmap_threshold_kb``), so a fresh 0.8 MB light table and three 0.3 MB images per frame
        cost page faults that tripled the prediction's CPU time (docs/performance.md).
        """
        bw, bh = self.box[2], self.box[3]
        if out is None or out.shape != (bh, bw) or out.dtype != np.float32:
            out = np.empty((bh, bw), np.float32)
        light = self._canvas_light(canvas_grey)
        if self.diffusion_px <= 0:
            cv2.remap(light, self._map1, self._map2, cv2.INTER_LINEAR, dst=out, borderMode=cv2.BORDER_CONSTANT,
                      borderValue=self._border)
        else:
            seen = cv2.remap(light, self._map1, self._map2, cv2.INTER_LINEAR, dst=self._seen,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=self._border)
            # Blur over the lit pixels only (normalised): nothing is known of the light beyond the band.
            seen[self._dark] = 0.0
            blurred = cv2.GaussianBlur(seen, (0, 0), self.diffusion_px, dst=self._blurred)
            np.divide(blurred[self._inner], self._lit_blur, out=out)
        out[self._uncovered] = 1.0
        return out

    __call__ = gain  # the touch service's ``predict(canvas, out)``

    def window(self, canvas_grey: np.ndarray, rows: slice, cols: slice) -> np.ndarray:
        """(rows, cols) of :meth:`gain`'s result (box pixels), computed there only (a new float32 array).

        Why: with ``[touch] detect_scale`` < 1 the touch pipeline reads the light at the coarse size everywhere and
        at this predictor's size only in the window around a candidate's shadows. The remap and the blur then run
        over the window and the blur's reach (:func:`feelium.skin.blurwindow.blur_window`, inside the box's own
        window), so the values are the whole prediction's: the same maps, the same kernel over the same pixels."""
        bh, bw = self._lit_blur.shape
        r0, r1, _ = rows.indices(bh)
        c0, c1, _ = cols.indices(bw)
        if r1 <= r0 or c1 <= c0:
            raise ValueError(f"window {rows}, {cols} is empty or outside the {bw}x{bh} box")
        return self._window_of(self._window_light(canvas_grey), r0, r1, c0, c1)

    def window_of_mix(self, parts: Sequence[tuple[np.ndarray, float]], rows: slice, cols: slice) -> np.ndarray:
        """:meth:`window` of the light of several canvases mixed with weights (``parts``: canvas, weight), as one
        camera exposure mixes the projector frames it saw (a new float32 array).

        Why: the prediction is linear in the light (the remap interpolates, the blur and the division by the lit
        weight are linear; the border's light and the uncovered pixels' 1.0 take the weights' sum), so the canvases'
        lights are mixed first, on the small reduced canvas, and the window is remapped and blurred once instead of
        once per canvas: equal to mixing the windows up to float rounding. The mix is kept for the next windows of
        the same parts: the fine pass's window and the pattern's lesson read the same exposure."""
        if len(parts) == 1:
            canvas, weight = parts[0]
            out = self.window(canvas, rows, cols)
            out *= np.float32(weight)
            return out
        bh, bw = self._lit_blur.shape
        r0, r1, _ = rows.indices(bh)
        c0, c1, _ = cols.indices(bw)
        if r1 <= r0 or c1 <= c0:
            raise ValueError(f"window {rows}, {cols} is empty or outside the {bw}x{bh} box")
        total = float(sum(weight for _, weight in parts))
        return self._window_of(self._mixed_light(parts), r0, r1, c0, c1, total)

    def _mixed_light(self, parts: Sequence[tuple[np.ndarray, float]]) -> np.ndarray:
        """The canvases' lights mixed with their weights, into the predictor's buffer; kept while the same parts (the
        same canvas arrays and weights) are asked for again."""
        key = self._mix_key
        if key is not None and len(key) == len(parts) and all(c is k and w == v for (c, w), (k, v) in zip(parts, key)):
            return self._mix
        for i, (canvas, weight) in enumerate(parts):
            light = self._window_light(canvas)
            if i == 0:
                if self._mix.shape != light.shape:
                    self._mix = np.empty_like(light)
                np.multiply(light, np.float32(weight), out=self._mix)
            else:
                cv2.scaleAdd(light, float(weight), self._mix, dst=self._mix)  # mix += weight * light, one pass
        self._mix_key = [(canvas, float(weight)) for canvas, weight in parts]
        return self._mix

    def _window_of(self, light: np.ndarray, r0: int, r1: int, c0: int, c1: int, total: float = 1.0) -> np.ndarray:
        """Rows ``r0:r1``, columns ``c0:c1`` of the box's light for a reduced canvas light (a new float32 array);
        ``total``: the weight the light was mixed with (what the border's light and the uncovered pixels' take)."""
        border = self._border * total
        iy, ix = self._inner[0].start, self._inner[1].start
        if self.diffusion_px <= 0:
            part = (slice(iy + r0, iy + r1), slice(ix + c0, ix + c1))
            out = cv2.remap(light, self._map1[part], self._map2[part], cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=border)
        else:
            mh, mw = self._map2.shape
            part = blur_window((mw, mh), (ix + c0, iy + r0, c1 - c0, r1 - r0), self.diffusion_px)
            # Into the front of whole-window buffers: contiguous, and no 0.2 MB allocation (an mmap) per call.
            shape = (part[0].stop - part[0].start, part[1].stop - part[1].start)
            seen = cv2.remap(light, self._map1[part], self._map2[part], cv2.INTER_LINEAR,
                             dst=_front(self._seen, shape), borderMode=cv2.BORDER_CONSTANT, borderValue=border)
            seen[self._dark[part]] = 0.0
            blurred = cv2.GaussianBlur(seen, (0, 0), self.diffusion_px, dst=_front(self._blurred, shape))
            y0, x0 = iy + r0 - part[0].start, ix + c0 - part[1].start
            out = blurred[y0 : y0 + r1 - r0, x0 : x0 + c1 - c0] / self._lit_blur[r0:r1, c0:c1]
        out[self._uncovered[r0:r1, c0:c1]] = total
        return out

    def _window_light(self, canvas_grey: np.ndarray) -> np.ndarray:
        """:meth:`_canvas_light` of a canvas, kept for the next windows of the same canvas: a projector frame lights
        one to three camera exposures, each of which may ask for windows (its candidates', the pattern's lesson),
        and a canvas is never rewritten once published (:mod:`feelium.touch.projected`). The oldest kept light's
        array is written over (a new 0.2 MB array per canvas would be an mmap in the daemon), the reduction straight
        into it (a copy of it cost a pass over 0.2 MB a projector frame, ~0.04 ms paced at 30 fps)."""
        for canvas, light in self._recent:
            if canvas is canvas_grey:
                return light
        rw, rh = self._reduced_size
        spare = self._recent.pop()[1] if len(self._recent) >= RECENT_CANVASES else np.empty((rh, rw), np.float32)
        light = self._canvas_light(canvas_grey, spare)
        if light is not spare:  # not reduced (a factor of 1): the look-up's own buffer
            np.copyto(spare, light)
        self._recent.insert(0, (canvas_grey, spare))
        return spare

    def _canvas_light(self, canvas_grey: np.ndarray, dst: np.ndarray | None = None) -> np.ndarray:
        """The canvas's light (linear, relative to the flat grey), reduced to about one canvas pixel per frame pixel
        (into ``dst`` when it is reduced and ``dst`` is given, else one of the predictor's buffers, valid until the
        next call). With a ``finer`` predictor reducing by half as
        much, its reduction (kept for its windows) is halved: the same values as reducing here (the mean of means
        of equal blocks, in the same steps), and the canvas is looked up and reduced once for both grids."""
        cw, ch = self.canvas_size
        if canvas_grey.shape != (ch, cw) or canvas_grey.dtype != np.uint8:
            raise ValueError(f"canvas must be {cw}x{ch} grey uint8, got {canvas_grey.shape} {canvas_grey.dtype}")
        finer = self._finer
        if finer is not None and finer.reduce * 2 == self.reduce and self.reduce in (4, 8):
            half = finer._window_light(canvas_grey)
            rw, rh = self._reduced_size
            if half.shape == (rh * 2, rw * 2):
                return cv2.resize(half, (rw, rh), dst=self._reduced, interpolation=cv2.INTER_AREA)
        light = cv2.LUT(canvas_grey, self._lut, dst=self._lut_out)
        if self._undrawn is not None:
            light.ravel()[self._undrawn] = self._border
        if self.reduce > 1:
            into = self._reduced if dst is None else dst
            light = _area_reduce(light, self.reduce, self._reduced_size, self._border, into)
        return light


def _front(buffer: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A C-contiguous ``shape`` array over the front of ``buffer``'s memory (as large or larger)."""
    return buffer.reshape(-1)[: shape[0] * shape[1]].reshape(shape)


def _renderer_camera_points(
    inv_x: np.ndarray, inv_y: np.ndarray, proj_x: np.ndarray, proj_y: np.ndarray, uncovered: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The camera point the renderer drew at each frame pixel's projector position, and whether it drew one.

    The renderer's projector -> camera map (the calibration's fitted inverse) is interpolated over its covered
    neighbours only, so a pixel at the patch's edge keeps its position instead of falling off it; whether the
    renderer drew the canvas there at all is its nearest projector pixel's, as its coverage test is.
    """
    drawn_p = (np.isfinite(inv_x) & np.isfinite(inv_y)).astype(np.float32)
    xs, ys = np.where(uncovered, _OFF, proj_x), np.where(uncovered, _OFF, proj_y)
    weight = sample(drawn_p, xs, ys, border=0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        cam_x = sample(np.where(drawn_p > 0, inv_x, 0.0), xs, ys, border=0.0) / weight
        cam_y = sample(np.where(drawn_p > 0, inv_y, 0.0), xs, ys, border=0.0) / weight
    nearest = cv2.remap(drawn_p, xs.astype(np.float32), ys.astype(np.float32), cv2.INTER_NEAREST,
                        borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    drawn = (nearest > 0) & (weight > 0) & ~uncovered
    return cam_x.astype(np.float32), cam_y.astype(np.float32), drawn


def _drawn_canvas(
    inv_x: np.ndarray, inv_y: np.ndarray, calibration: ProjectorMap, canvas_size: tuple[int, int], face: FaceModel | None
) -> np.ndarray:
    """(h, w) bool over the canvas: pixels a bilinear tap of the renderer's warp reads (as the renderer maps).

    The projector's grid is taken in bands of rows (:data:`CANVAS_MAP_BAND_POINTS`): its whole 1280x720 at once
    held ~40 MB of index arrays on top of the maps' own, at the daemon's start-up peak (session 25)."""
    cw, ch = canvas_size
    drawn = np.zeros((ch, cw), bool)
    rows = max(1, CANVAS_MAP_BAND_POINTS // max(1, inv_x.shape[1]))
    for top in range(0, inv_x.shape[0], rows):
        band = slice(top, top + rows)
        map_x, map_y = canvas_map(inv_x[band], inv_y[band], calibration, canvas_size, face)
        on = np.isfinite(map_x) & np.isfinite(map_y)
        x0 = np.floor(map_x[on]).astype(np.int64)
        y0 = np.floor(map_y[on]).astype(np.int64)
        for dx in (0, 1):
            for dy in (0, 1):
                x, y = x0 + dx, y0 + dy
                keep = (x >= 0) & (x < cw) & (y >= 0) & (y < ch)
                drawn[y[keep], x[keep]] = True
    return drawn


def _scale(map_x: np.ndarray, map_y: np.ndarray, off: np.ndarray) -> float:
    """Median map units per pixel step over the pixels the map covers (the smaller of the two axes)."""
    dx = np.hypot(np.diff(map_x, axis=1), np.diff(map_y, axis=1))[~(off[:, 1:] | off[:, :-1])]
    dy = np.hypot(np.diff(map_x, axis=0), np.diff(map_y, axis=0))[~(off[1:] | off[:-1])]
    if dx.size == 0 or dy.size == 0:
        return 1.0
    return min(float(np.median(dx)), float(np.median(dy)))


def _reduction(map_x: np.ndarray, map_y: np.ndarray, off: np.ndarray) -> int:
    """The integer canvas reduction giving about one canvas pixel per camera pixel (median over the patch)."""
    return max(1, int(np.floor(_scale(map_x, map_y, off) + 0.25)))


def _area_reduce(light: np.ndarray, factor: int, size: tuple[int, int], pad: float, dst: np.ndarray) -> np.ndarray:
    """Average ``factor`` x ``factor`` blocks into ``dst``; a canvas not a multiple of ``factor`` is padded with
    ``pad``. A factor of 4 or 8 is taken as halvings (the mean of means of equal blocks is the mean): OpenCV's area
    resize has a fast path for 2 only, and its general one took 0.18 ms a 512x384 canvas where two halvings take
    ~0.06 (the coarse touch pass predicts its light with 4)."""
    rw, rh = size
    h, w = light.shape
    if (rw * factor, rh * factor) != (w, h):
        light = cv2.copyMakeBorder(light, 0, rh * factor - h, 0, rw * factor - w, cv2.BORDER_CONSTANT, value=pad)
    while factor in (4, 8):
        light = cv2.resize(light, (light.shape[1] // 2, light.shape[0] // 2), interpolation=cv2.INTER_AREA)
        factor //= 2
    return cv2.resize(light, (rw, rh), dst=dst, interpolation=cv2.INTER_AREA)
