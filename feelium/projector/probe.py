"""Laying the probe (:mod:`feelium.skin.probe`) over the projector's frames, through the calibration map.

The probe's checkerboard is defined in camera pixels (where touch learns from
it), so each projector pixel takes the sign of the cell the camera sees it in
(the calibration's inverse map); projector pixels the camera does not see are
left alone, and only the bounding box of those it sees is touched.

A frame is modulated through two lookup tables, one per sign: each grey value
goes to the value whose light (gamma and black level, :func:`light_table`) is
closest to ``1 +- level`` times its own. Cheap (two table lookups and a masked
copy of the box: about 5 ms for a whole 1280x720 frame on the shared x86
machine), but 8-bit: at the flat grey (217) a 3 % change of light is about 3
grey levels, so the sinusoid is a staircase. The level published for touch is
therefore the one *realised* at the flat grey (half the difference between the
plus and the minus cells' light there), not the nominal one: on a static skin
the sensing patch is mostly that grey, and there the regression sees exactly
what was shown. Pixels of other greys are off by at most half a grey level's
light (documented in docs/projector.md, *The probe*).
"""

from __future__ import annotations

import cv2
import numpy as np

from feelium.projector.canvaslight import light_table
from feelium.projector.config import ProjectorConfig
from feelium.skin.probe import cell_for
from feelium.skin.projector_map import CalibrationError, ProjectorMap


class ProbeOverlay:
    """Modulates projector frames by the probe at a given level (one instance per calibration)."""

    def __init__(self, config: ProjectorConfig, calibration: ProjectorMap) -> None:
        self._light = light_table(config, calibration).astype(np.float64)  # light per grey, 1.0 at the flat grey
        self._flat = int(round(config.flat_level * 255.0))
        try:
            cam_x, cam_y = calibration.projector_to_camera()
        except CalibrationError:
            cam_x = cam_y = np.full((config.height, config.width), np.nan, np.float32)
        seen = np.isfinite(cam_x) & np.isfinite(cam_y)
        cell = cell_for(calibration.camera_size[0])
        ys, xs = np.nonzero(seen)
        if len(xs) == 0:
            self._box = None
            return
        y0, y1, x0, x1 = int(ys.min()), int(ys.max()) + 1, int(xs.min()), int(xs.max()) + 1
        self._box = (y0, y1, x0, x1)
        cx = np.nan_to_num(cam_x[y0:y1, x0:x1], nan=-1.0)
        cy = np.nan_to_num(cam_y[y0:y1, x0:x1], nan=-1.0)
        plus = ((np.floor(cx / cell) + np.floor(cy / cell)) % 2 == 0) & seen[y0:y1, x0:x1]
        minus = ~plus & seen[y0:y1, x0:x1]
        self._plus = plus.astype(np.uint8)
        self._minus = minus.astype(np.uint8)
        self._buffer: np.ndarray | None = None

    def table(self, level: float) -> np.ndarray:
        """(256,) uint8: each grey value to the one whose light is closest to ``1 + level`` times its own."""
        target = self._light * (1.0 + level)
        # the light table increases with the grey value: the nearest of the two neighbours of each target
        hi = np.clip(np.searchsorted(self._light, target), 1, 255)
        lo = hi - 1
        nearest = np.where(np.abs(self._light[lo] - target) <= np.abs(self._light[hi] - target), lo, hi)
        nearest[0] = 0  # black stays black: no light to modulate
        return nearest.astype(np.uint8)

    def realised(self, level: float) -> float:
        """The level a frame modulated at ``level`` shows at the flat grey: half the plus and minus cells' difference."""
        flat = self._light[self._flat]
        up = self._light[self.table(level)[self._flat]] / flat
        down = self._light[self.table(-level)[self._flat]] / flat
        return float((up - down) / 2.0)

    def lay(self, frame: np.ndarray, level: float) -> tuple[np.ndarray, float]:
        """A copy of ``frame`` (projector pixels, BGR or grey uint8) with the probe at ``level``, and the level
        realised at the flat grey (what touch is told). The frame itself is never written (the renderer may show
        it again); the returned one is a new array each call (the display and the preview may still hold the last)."""
        if self._box is None:
            return frame, 0.0
        y0, y1, x0, x1 = self._box
        out = frame.copy()
        box = frame[y0:y1, x0:x1]
        up = cv2.LUT(box, self.table(level))
        down = cv2.LUT(box, self.table(-level))
        target = out[y0:y1, x0:x1]
        cv2.copyTo(up, self._plus, target)
        cv2.copyTo(down, self._minus, target)
        return out, self.realised(level)
