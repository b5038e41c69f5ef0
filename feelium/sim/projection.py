"""Projected content as the rear camera sees it, through a known fisheye-like warp.

The simulator's back-light ``B`` is what a flat projection gives. Whatever the
projector really shows (a calibration pattern, the wearer's face) scales it
point by point: the membrane spot seen by camera pixel ``(x, y)`` is lit by
projector pixel ``warp(x, y)``, whose light is ``black + (1 - black) * (value / 255) ^ gamma``
relative to white, blurred a little by the membrane. :class:`ProjectedLight`
turns a projector frame into that multiplicative factor in camera coordinates,
normalised to the flat grey the session was calibrated with, which is exactly
the ``projected`` hook of :class:`feelium.sim.scene.SceneRenderer`.

Because the warp is known here, a calibration decoded from simulated camera
frames can be scored against the truth (:meth:`FisheyeWarp.truth_map`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import cv2
import numpy as np

from feelium.sim.scene import ROI, SceneRenderer, SceneState, Session
from feelium.skin.face import FaceModel


@dataclass(frozen=True)
class FisheyeWarp:
    """Camera pixel to projector pixel: barrel-distorted radial map with a rotation and an off-axis centre.

    ``p = pc + R(rot) * diag(sx, sy) * d * (1 + k1 |d|^2 + k2 |d|^4)`` with
    ``d = (x - cx, y - cy) / f``: the strong barrel compression a 180 degree
    fisheye gives towards the edge of the patch.
    """

    cx: float = 326.0
    cy: float = 236.0
    f: float = 300.0
    k1: float = -0.19
    k2: float = 0.025
    sx: float = 560.0
    sy: float = 548.0
    rot_deg: float = 2.0
    pcx: float = 642.0
    pcy: float = 358.0

    def camera_to_projector(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dx = (np.asarray(x, np.float64) - self.cx) / self.f
        dy = (np.asarray(y, np.float64) - self.cy) / self.f
        r2 = dx * dx + dy * dy
        radial = 1.0 + self.k1 * r2 + self.k2 * r2 * r2
        ux, uy = self.sx * dx * radial, self.sy * dy * radial
        c, s = math.cos(math.radians(self.rot_deg)), math.sin(math.radians(self.rot_deg))
        return self.pcx + c * ux - s * uy, self.pcy + s * ux + c * uy

    def scaled(self, k: float) -> "FisheyeWarp":
        """The same optics seen by a camera of ``k`` times this one's resolution (camera point ``(x, y)`` there is
        ``(x / k, y / k)`` here). Why: the whole face's frame (1280x960) is the protocol's 640x480 camera at twice
        the resolution, as the daemon's renderer assumes when it scales a calibration onto the face's frame."""
        return replace(self, cx=self.cx * k, cy=self.cy * k, f=self.f * k)

    def truth_map(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """(H, W) float32 projector x and y of every camera pixel."""
        xs, ys = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
        px, py = self.camera_to_projector(xs, ys)
        return px.astype(np.float32), py.astype(np.float32)


@dataclass(frozen=True)
class ProjectorOptics:
    """How the simulated projector's pixel values become light on the membrane."""

    gamma: float = 2.2
    black: float = 0.035  # light of a black pixel relative to white
    blur_px: float = 1.2  # projector defocus plus membrane diffusion, in projector px
    flat_level: float = 0.85  # grey (0..1) of the flat projection the session's back-light B stands for


class ProjectedLight:
    """Projector frames to the camera-space multiplicative back-light factor."""

    def __init__(self, warp: FisheyeWarp, camera_size: tuple[int, int], optics: ProjectorOptics = ProjectorOptics()) -> None:
        self.warp = warp
        self.optics = optics
        w, h = camera_size
        self.map_x, self.map_y = warp.truth_map(w, h)
        self._flat = self._light(np.float32(optics.flat_level))
        # The light of each of the 256 grey levels, looked up per pixel: the same float32 values as computing
        # the power law on every pixel of a frame (elementwise, so bit for bit), 10x cheaper on the face's frame.
        self._table = self._light(np.arange(256, dtype=np.float32) * np.float32(1.0 / 255.0))

    def _light(self, level: np.ndarray | np.float32) -> np.ndarray:
        o = self.optics
        return o.black + (1.0 - o.black) * np.power(level, o.gamma, dtype=np.float32)

    def factor(self, frame: np.ndarray) -> np.ndarray:
        """(H, W) float32 factor of projector frame ``frame`` (gray or BGR uint8) relative to the flat projection."""
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame
        light = cv2.LUT(gray, self._table)
        if self.optics.blur_px > 0:
            light = cv2.GaussianBlur(light, (0, 0), self.optics.blur_px)
        black = float(self.optics.black)
        seen = cv2.remap(light, self.map_x, self.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=black)
        return (seen / self._flat).astype(np.float32)


FrameSource = Callable[[float], "np.ndarray | None"]


def projected_hook(light: ProjectedLight, source: FrameSource) -> Callable[[float], np.ndarray | None]:
    """The scene renderer's ``projected`` hook: camera time to the factor of what the projector shows then.

    ``source(t)`` returns the projector frame on screen at ``t`` (or None for
    the flat projection); a repeated frame object is converted only once.
    """
    last: list[object] = [None, None]

    def hook(t: float) -> np.ndarray | None:
        frame = source(t)
        if frame is None:
            return None
        if frame is not last[0]:
            last[0], last[1] = frame, light.factor(frame)
        return last[1]  # type: ignore[return-value]

    return hook


def exposure_weights(t: float, exposure_s: float, fps: float, latency_s: float) -> list[tuple[int, float]]:
    """Projector frame indices lit during the camera exposure centred on ``t``, with their share of it.

    Projector frame ``k`` is on the membrane during ``[k / fps + latency, (k + 1) / fps + latency)``;
    light adds linearly, so the camera integrates each frame in proportion to its overlap with the exposure.
    A zero exposure samples the frame on screen at ``t``.
    """
    start = t - latency_s - exposure_s / 2.0
    if exposure_s <= 0.0:
        return [(int(math.floor(start * fps + 1e-9)), 1.0)]
    end = start + exposure_s
    out = []
    k = int(math.floor(start * fps + 1e-9))
    while k / fps < end:
        overlap = min(end, (k + 1) / fps) - max(start, k / fps)
        if overlap > 0.0:
            out.append((k, overlap / exposure_s))
        k += 1
    return out


def timed_hook(
    light: ProjectedLight, frame_at: Callable[[int], np.ndarray], fps: float, latency_s: float, exposure_s: float
) -> Callable[[float], np.ndarray]:
    """The ``projected`` hook for a projector running at ``fps`` with ``latency_s`` behind its frame clock.

    ``frame_at(k)`` is projector frame ``k`` (shown from ``k / fps``); each camera frame gets the
    exposure-weighted mix of the frames lit while it integrated, so a cut or a fade straddles exposures
    as it does on a real sensor.
    """
    cache: dict[int, np.ndarray] = {}

    def hook(t: float) -> np.ndarray:
        mix: np.ndarray | None = None
        for k, w in exposure_weights(t, exposure_s, fps, latency_s):
            if k not in cache:
                if len(cache) > 8:
                    cache.pop(min(cache))
                cache[k] = light.factor(frame_at(k))
            mix = cache[k] * np.float32(w) if mix is None else mix + cache[k] * np.float32(w)
        assert mix is not None
        return mix

    return hook


class SimPatternCapture:
    """Shows patterns on a simulated projector and captures the rear camera through the scene simulator.

    Implements the capture seam of :mod:`feelium.lab.projector.calibrate`: ``show``
    puts a pattern on the projector, each ``capture`` advances the camera clock
    by one frame period and renders an empty scene lit by it.
    """

    def __init__(
        self, session: Session, light: ProjectedLight, rng: np.random.Generator, fps: float = 15.0, face: FaceModel | None = None
    ) -> None:
        """``face``: the whole curved front face (its frame and box, the envelope black off it) instead of the
        paper's patch; ``light`` must then be at the face's frame size."""
        self._light = light
        self._factor: np.ndarray | None = None
        roi = ROI if face is None else face.roi()
        self._renderer = SceneRenderer(session, rng, roi=roi, projected=lambda t: self._factor, face=face)
        self._period = 1.0 / fps
        self._t = 0.0
        self.camera_size = (self._renderer.width, self._renderer.height)
        self.roi = self._renderer.roi

    def show(self, pattern: np.ndarray) -> None:
        self._factor = self._light.factor(pattern)

    @property
    def last_t(self) -> float:
        """The newest frame's time on the simulated camera's clock."""
        return self._t

    def capture(self) -> np.ndarray:
        self._t += self._period
        return self._renderer.frame(self._t, SceneState())
