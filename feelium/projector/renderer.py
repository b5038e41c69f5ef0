"""The projector's frame: layers on the skin canvas, warped through the calibration to projector pixels.

Layers are composed on a *skin canvas* that spans the camera's sensitive
patch (u, v in 0..1, the touch events' own coordinates): the wearer's face (or
the default avatar), then every answer at the spot it answers. One remap with
a precomputed fixed-point map then carries the canvas to the projector's
native resolution (onto the coarsest grid that keeps every canvas pixel, scaled up:
:mod:`feelium.projector.optics`), so what is meant for a spot on the skin lands there through
the fisheye, and a circle drawn on the canvas is a circle on the skin.

Time, face image and answers in, a BGR frame out; the state kept between frames is the previous canvas and
frame, so that only what changed is re-warped (the result is the full warp's), what the newest frame showed,
so that a frame with nothing new costs nothing, and the drawing round's strokes, each drawn once
(:class:`~feelium.projector.strokes.StrokeLayer`).
"""

from __future__ import annotations

import threading
from collections.abc import Hashable, Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from feelium.interactions.answers import Answer
from feelium.projector.avatar import BACKGROUND_BGR, Avatar
from feelium.skin.face import FaceModel
from feelium.skin.projector_map import ProjectorMap
from feelium.projector.config import ProjectorConfig
from feelium.projector.layers import DRAWERS
from feelium.projector.lift import SensingLift
from feelium.projector.optics import OFF_SKIN, canvas_density, coarse_maps, fit_box, warp_scale
from feelium.projector.strokes import StrokeLayer
from feelium.projector.tilewarp import TileWarp


# Points a band of :func:`canvas_map` maps at once: the face's ray casting keeps ~15 float64 temporaries of its input's
# size alive, 110 MB at once for the projector's 1280x720 grid, which made the daemon's start-up peak (its memory,
# not its steady state) 28 MB over its steady resident size (session 25). A band of 64k points keeps them ~8 MB.
CANVAS_MAP_BAND_POINTS = 65536


def canvas_map(
    cam_x: np.ndarray, cam_y: np.ndarray, calibration: ProjectorMap, canvas_size: tuple[int, int], face: FaceModel | None
) -> tuple[np.ndarray, np.ndarray]:
    """Canvas pixel (centres on integers) of camera points in the calibration's pixels; NaN off the skin.

    Without a face model the canvas spans the calibration's ROI linearly; with
    one, it spans the face's u, v (the model may be for another frame size:
    camera points are scaled onto its frame first), which is what the touch
    pipeline reports with the same model, so an answer lands where the touch was.
    With a face, a grid of many rows is mapped in bands of rows (:data:`CANVAS_MAP_BAND_POINTS`): each point's
    arithmetic is its own, so the bits are those of one pass.
    """
    if face is None:
        cw, ch = canvas_size
        rx, ry, rw, rh = calibration.roi
        return (cam_x - rx) * np.float32(cw / rw), (cam_y - ry) * np.float32(ch / rh)
    if cam_x.ndim != 2 or cam_x.size <= CANVAS_MAP_BAND_POINTS:
        return _face_canvas_map(cam_x, cam_y, calibration, canvas_size, face)
    map_x, map_y = np.empty(cam_x.shape, np.float32), np.empty(cam_x.shape, np.float32)
    rows = max(1, CANVAS_MAP_BAND_POINTS // cam_x.shape[1])
    for top in range(0, cam_x.shape[0], rows):
        band = slice(top, top + rows)
        map_x[band], map_y[band] = _face_canvas_map(cam_x[band], cam_y[band], calibration, canvas_size, face)
    return map_x, map_y


def _face_canvas_map(
    cam_x: np.ndarray, cam_y: np.ndarray, calibration: ProjectorMap, canvas_size: tuple[int, int], face: FaceModel
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`canvas_map` with a face model, in one pass."""
    cw, ch = canvas_size
    kw, kh = calibration.camera_size
    fx = (cam_x.astype(np.float64) + 0.5) * (face.width / kw) - 0.5
    fy = (cam_y.astype(np.float64) + 0.5) * (face.height / kh) - 0.5
    u, v = face.to_uv(fx, fy)
    on = np.isfinite(u) & np.isfinite(v) & (u >= 0.0) & (u < 1.0) & (v >= 0.0) & (v < 1.0)
    map_x = np.where(on, u * cw - 0.5, np.nan).astype(np.float32)
    map_y = np.where(on, v * ch - 0.5, np.nan).astype(np.float32)
    return map_x, map_y


class Renderer:
    """Renders projector frames for one calibration."""

    def __init__(self, config: ProjectorConfig, calibration: ProjectorMap, face: FaceModel | None = None) -> None:
        """``face``: with the touch side's face model the canvas spans the face (its u, v: azimuth and elevation
        on the envelope), as touch events do then; without, it spans the calibration's ROI."""
        if calibration.projector_size != (config.width, config.height):
            raise ValueError(
                f"calibration is for a {calibration.projector_size[0]}x{calibration.projector_size[1]} projector, "
                f"config says {config.width}x{config.height}; recalibrate with `feelium calibrate projector`"
            )
        self.config = config
        self.calibration = calibration
        self.canvas_size = (config.canvas_width, config.canvas_height)
        cw, ch = self.canvas_size
        inv_x, inv_y = calibration.projector_to_camera()
        map_x, map_y = canvas_map(inv_x, inv_y, calibration, self.canvas_size, face)
        off = ~(np.isfinite(map_x) & np.isfinite(map_y))
        # Projector pixels that land on the sensitive patch, kept as bits (0.1 MB; a bool frame is 0.9 MB).
        self._covered_bits = np.packbits(~off)
        # Only the covered box is remapped each frame; the rest of the frame is the constant border.
        ys, xs = np.nonzero(~off)
        if len(xs) == 0:
            raise ValueError("the calibration covers no projector pixel")
        self._box = (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1)
        frame_size = (config.width, config.height)
        # Warped on the coarsest grid that keeps every canvas pixel, then scaled up (feelium.projector.optics).
        self.warp_scale = warp_scale(canvas_density(map_x, map_y)) if config.warp_resolution == "optics" else (1, 1)
        if self.warp_scale != (1, 1):
            self._box = fit_box(self._box, frame_size, self.warp_scale[1])
            map1, map2 = coarse_maps(map_x, map_y, self._box, self.warp_scale)
        else:
            map_x[off] = OFF_SKIN
            map_y[off] = OFF_SKIN
            x0, y0, x1, y1 = self._box
            map1, map2 = cv2.convertMaps(map_x[y0:y1, x0:x1], map_y[y0:y1, x0:x1], cv2.CV_16SC2)
        border = tuple(int(c * 0.5) for c in BACKGROUND_BGR)
        self.tiles = TileWarp(map1, map2, self._box, self.canvas_size, frame_size, border, self.warp_scale)
        self.avatar = Avatar(cw, ch)
        self._last: _Shown | None = None
        self._canvas = np.empty((ch, cw, 3), np.uint8)
        self._canvas_lock = threading.Lock()  # render() may be called from two threads (the service, a preview)
        self.skipped: dict[str, int] = {}
        self.lift = SensingLift(config.sensing_floor, config.fade_floor)
        self.strokes = StrokeLayer(cw, ch)
        self._answer_period = 1.0 / config.answer_fps
        self.rendered = 0  # frames drawn (the rest were the previous frame shown again)

    @property
    def covered(self) -> np.ndarray:
        """(H_p, W_p) bool: projector pixels that land on the sensitive patch (unpacked on each call)."""
        shape = (self.config.height, self.config.width)
        return np.unpackbits(self._covered_bits, count=shape[0] * shape[1]).astype(bool).reshape(shape)

    def fit_face(self, face: np.ndarray) -> np.ndarray:
        """The wearer's face image scaled to cover the canvas (centre crop), BGR uint8."""
        cw, ch = self.canvas_size
        if face.ndim == 2:
            face = cv2.cvtColor(face, cv2.COLOR_GRAY2BGR)
        h, w = face.shape[:2]
        scale = max(cw / w, ch / h)
        resized = cv2.resize(face, (max(cw, int(round(w * scale))), max(ch, int(round(h * scale)))), interpolation=cv2.INTER_AREA)
        y0 = (resized.shape[0] - ch) // 2
        x0 = (resized.shape[1] - cw) // 2
        return np.ascontiguousarray(resized[y0 : y0 + ch, x0 : x0 + cw])

    def canvas(
        self, now: float, face: np.ndarray | None, answers: Iterable[Answer], talking: bool = False, out: np.ndarray | None = None
    ) -> np.ndarray:
        """The skin canvas at ``now``: ``face`` (already canvas-sized, see :meth:`fit_face`) or the avatar, plus
        answers; drawn into ``out`` (a canvas-sized BGR array) when given, else into a new array."""
        cw, ch = self.canvas_size
        if face is not None and face.shape[:2] != (ch, cw):
            raise ValueError(f"face is {face.shape[1]}x{face.shape[0]}, canvas is {cw}x{ch}; use fit_face()")
        img = out if out is not None else np.empty((ch, cw, 3), np.uint8)
        if face is not None:
            np.copyto(img, face)
        else:
            self.avatar.render(now, talking=talking, out=img)
        self.lift.measure(img)  # on the picture alone: answers are drawn over it and lifted with it
        answers = tuple(answers)
        self.strokes.update([a for a in answers if a.kind == "stroke"])
        strokes_laid = False
        for answer in answers:
            if answer.kind == "stroke":  # the round's strokes, drawn once each, laid where the first one comes
                if not strokes_laid:
                    self.strokes.compose(img)
                    strokes_laid = True
                continue
            drawer = DRAWERS.get(answer.kind)
            if drawer is None:
                self.skipped[answer.kind] = self.skipped.get(answer.kind, 0) + 1
                continue
            drawer(img, answer, now)
        self.lift.apply(img)  # keep the skin lit enough to sense touch (feelium.projector.lift)
        return img

    def warp(self, canvas: np.ndarray) -> np.ndarray:
        """Carry a canvas to projector pixels (H_p, W_p, 3) through the calibration.

        Only what changed since the previous call is re-warped (:class:`TileWarp`); the frame equals the
        full warp's. The returned frame is not written again while anyone holds it.
        """
        return self.tiles.warp(canvas)

    def render(self, now: float, face: np.ndarray | None, answers: Iterable[Answer], talking: bool = False) -> np.ndarray:
        """The projector frame at ``now`` (see :meth:`render_with_canvas`)."""
        return self.render_with_canvas(now, face, answers, talking)[0]

    def render_with_canvas(
        self, now: float, face: np.ndarray | None, answers: Iterable[Answer], talking: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """The projector frame at ``now`` and its skin canvas in grey (what the touch side predicts the back-light
        from: :class:`feelium.projector.canvaslight.CanvasLightPredictor`; 0.2 MB against the frame's 2.7 MB).
        Neither is written again once returned, and a frame shown again comes with the same canvas array.

        The canvas is drawn into one reused buffer: a new 0.6 MB array per frame would be an mmap and its page
        faults under the daemon's malloc settings (``[daemon]``). A frame that would show what the previous one
        shows is the previous one, returned without drawing, lifting, warping or comparing anything: the same face
        array (a face is never changed in place) or avatar pose, the same stroke layer, the same answer objects
        (the engine replaces an answer it changes) and strokes drawn less than ``1 / answer_fps`` ago. So answers
        move and strokes grow on screen at ``answer_fps`` when nothing else changes, and with every new face frame
        when it does (a face video carries them along); a new or ended answer or stroke shows at once.
        """
        answers = tuple(answers)
        with self._canvas_lock:
            pose = None if face is not None else self.avatar.pose(now, talking)
            moving = tuple(a for a in answers if a.kind != "stroke")
            version = self.strokes.update([a for a in answers if a.kind == "stroke"])
            last = self._last
            if last is not None and last.shows(face, pose, self.strokes.keys, moving):
                still = not moving and version == last.strokes  # nothing that moves, no stroke grew
                if still or 0.0 <= now - last.at < self._answer_period:
                    return last.frame, last.grey
            canvas = self.canvas(now, face, answers, talking, out=self._canvas)
            frame = self.warp(canvas)
            grey = cv2.cvtColor(canvas, cv2.COLOR_BGR2GRAY)
            self._last = _Shown(face, pose, version, self.strokes.keys, moving, now, frame, grey)
            self.rendered += 1
            return frame, grey


@dataclass(frozen=True, eq=False)
class _Shown:
    """The newest frame drawn, and what it shows: the face array itself or the avatar's pose, the stroke layer's
    version, the other answers (the very objects: the engine replaces an answer it changes) and their time."""

    face: np.ndarray | None
    pose: tuple[int, ...] | None
    strokes: int  # the stroke layer's version
    stroke_keys: tuple[Hashable, ...]  # which strokes it holds
    moving: tuple[Answer, ...]
    at: float  # the time the answers were drawn at
    frame: np.ndarray
    grey: np.ndarray  # its canvas in grey

    def shows(
        self, face: np.ndarray | None, pose: tuple[int, ...] | None, stroke_keys: tuple[Hashable, ...], moving: tuple[Answer, ...]
    ) -> bool:
        """The same picture and the same answers, though maybe at another time (strokes maybe longer)."""
        return (
            face is self.face
            and (face is not None or pose == self.pose)
            and stroke_keys == self.stroke_keys
            and len(moving) == len(self.moving)
            and all(a is b for a, b in zip(moving, self.moving))
        )
