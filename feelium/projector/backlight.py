"""Predicting what projected content does to the back-light the rear camera sees, from the projector's frame.

The daemon predicts from the skin canvas instead (:mod:`feelium.projector.canvaslight`: the same light in
a third of the time, from 0.2 MB instead of 2.7); this frame-based one stays as the reference it is checked
against and for the lab's experiments that start from projector frames.

The projector *is* the back-light: a dark pixel of the wearer's face dims the
membrane behind it exactly like a shadow would. The touch service turns this
prediction into the projected light of each exposure
(``TouchPipeline.process(..., projected_light=...)``, ``feelium/touch/projected.py``),
so a moving face is not mistaken for a touch. The prediction follows the light
path: projector value -> light (gamma, black level) -> membrane spot (the
calibration map) -> a little diffusion, relative to the flat grey the
pipeline's reference was learned under. Camera pixels the calibration does
not cover get 1.0 (no correction).
"""

from __future__ import annotations

import cv2
import numpy as np

from feelium.skin.projector_map import ProjectorMap
from feelium.projector.canvaslight import area_sigma, light_table
from feelium.projector.config import ProjectorConfig


_REDUCE = 2


class BacklightPredictor:
    """Projector frame in, per-camera-pixel back-light gain (float32, ~1.0 = flat) out."""

    def __init__(
        self,
        config: ProjectorConfig,
        calibration: ProjectorMap,
        frame_size: tuple[int, int] | None = None,
        *,
        average_of: int = 1,
    ) -> None:
        """``frame_size``: (width, height) of the frames the touch pipeline gets; default the calibration's camera size.
        ``average_of``: as :class:`feelium.projector.canvaslight.CanvasLightPredictor`'s (a coarser grid's light)."""
        self.config = config
        cw, ch = calibration.camera_size
        fw, fh = frame_size if frame_size is not None else (cw, ch)
        map_x, map_y = calibration.proj_x, calibration.proj_y
        if (fw, fh) != (cw, ch):
            map_x = cv2.resize(map_x, (fw, fh), interpolation=cv2.INTER_LINEAR)
            map_y = cv2.resize(map_y, (fw, fh), interpolation=cv2.INTER_LINEAR)
        self._uncovered = ~(np.isfinite(map_x) & np.isfinite(map_y))
        # The projector frame is first reduced by _REDUCE with area averaging: a camera pixel sees
        # about two projector pixels through the fisheye, so sampling the full frame would alias at edges.
        map_x = np.where(self._uncovered, -10.0, (map_x + 0.5) / _REDUCE - 0.5).astype(np.float32)
        map_y = np.where(self._uncovered, -10.0, (map_y + 0.5) / _REDUCE - 0.5).astype(np.float32)
        self._map1, self._map2 = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
        self.frame_size = (fw, fh)
        self.diffusion_px = config.diffusion_px * fw / cw
        if average_of > 1:
            self.diffusion_px = float(np.hypot(self.diffusion_px, area_sigma(average_of)))
        covered = (~self._uncovered).astype(np.float32)
        self._coverage_blur = np.maximum(
            cv2.GaussianBlur(covered, (0, 0), self.diffusion_px) if self.diffusion_px > 0 else covered, 1e-3
        )
        self._lut = light_table(config, calibration)  # gain per projector grey level

    def gain(self, projector_frame: np.ndarray) -> np.ndarray:
        """(H, W) float32 gain at the touch pipeline's frame size for a projector frame (BGR or gray uint8)."""
        pw, ph = self.config.width, self.config.height
        if projector_frame.shape[:2] != (ph, pw):
            raise ValueError(f"projector frame is {projector_frame.shape[1]}x{projector_frame.shape[0]}, expected {pw}x{ph}")
        gray = cv2.cvtColor(projector_frame, cv2.COLOR_BGR2GRAY) if projector_frame.ndim == 3 else projector_frame
        light = cv2.LUT(gray, self._lut)  # light is linear: average it, not the grey values (cv2.LUT: ~4x numpy's take)
        if _REDUCE > 1:
            light = cv2.resize(light, (pw // _REDUCE, ph // _REDUCE), interpolation=cv2.INTER_AREA)
        seen = cv2.remap(light, self._map1, self._map2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=1.0)
        if self.diffusion_px > 0:
            # Blur over covered pixels only (normalised), so the patch's border does not mix in the 1.0 outside.
            seen[self._uncovered] = 0.0
            seen = cv2.GaussianBlur(seen, (0, 0), self.diffusion_px) / self._coverage_blur
        seen[self._uncovered] = 1.0
        return seen
