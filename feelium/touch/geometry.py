"""Where the pipeline looks: the ROI cut out of the camera frame at the working resolution.

All heavy work runs on the ROI only, resized by the factor that maps the whole
camera frame to ``[touch] width x height``, so thresholds in camera pixels mean
the same at every working resolution and results map back exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


# (frame size, box [x, y, w, h]) a projected-light predictor is built for (WorkingGeometry.light_grid).
LightGrid = tuple[tuple[int, int], tuple[int, int, int, int]]


@dataclass(frozen=True)
class LightGrids:
    """Where a pipeline that detects coarser wants its projected light predicted (``TouchPipeline.light_grids``)."""

    coarse: LightGrid  # the detection grid: the whole exposure's light, every frame
    fine: LightGrid | None  # the working resolution's grid: windows of it, for the fine pass (None: upsampled)
    # Working pixels per detection pixel along each axis: the coarse light stands for their mean, as the working
    # resolution's light area-averaged did (see feelium.projector.canvaslight.area_sigma).
    average_of: int


@dataclass(frozen=True)
class WorkingGeometry:
    """The mapping between camera pixels and the working image of the ROI."""

    frame_size: tuple[int, int]  # (width, height) of the camera frames
    roi: tuple[int, int, int, int]  # [x, y, w, h] in camera pixels
    work_size: tuple[int, int]  # (width, height) of the working image of the ROI
    dtype: type

    @classmethod
    def build(
        cls,
        frame_size: tuple[int, int],
        roi: tuple[int, int, int, int] | None,
        work_frame_size: tuple[int, int],
        dtype: type = np.float32,
    ) -> "WorkingGeometry":
        fw, fh = (int(v) for v in frame_size)
        if fw <= 0 or fh <= 0:
            raise ValueError(f"frame_size must be positive, got {frame_size}")
        if roi is None:
            roi = (0, 0, fw, fh)
        x, y, w, h = (int(v) for v in roi)
        if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > fw or y + h > fh:
            raise ValueError(f"roi {list(roi)} does not fit the {fw}x{fh} frame")
        sx, sy = work_frame_size[0] / fw, work_frame_size[1] / fh
        ww, wh = max(4, int(round(w * sx))), max(4, int(round(h * sy)))
        return cls((fw, fh), (x, y, w, h), (ww, wh), dtype)

    @property
    def scale(self) -> tuple[float, float]:
        """Working pixels per camera pixel along x and y."""
        return self.work_size[0] / self.roi[2], self.work_size[1] / self.roi[3]

    @property
    def area_scale(self) -> float:
        """Camera pixels per working pixel (to report areas in camera pixels)."""
        sx, sy = self.scale
        return 1.0 / (sx * sy)

    def px(self, camera_px: float) -> float:
        """A length in camera pixels expressed in working pixels."""
        sx, sy = self.scale
        return camera_px * 0.5 * (sx + sy)

    def to_camera(self, wx: float, wy: float) -> tuple[float, float]:
        """Working-image coordinates (pixel centres at integers) to camera pixels."""
        sx, sy = self.scale
        x, y, _, _ = self.roi
        return x + (wx + 0.5) / sx - 0.5, y + (wy + 0.5) / sy - 0.5

    def from_camera(self, cx: float, cy: float) -> tuple[float, float]:
        """Camera pixels to working-image coordinates (the inverse of :meth:`to_camera`)."""
        sx, sy = self.scale
        x, y, _, _ = self.roi
        return (cx - x + 0.5) * sx - 0.5, (cy - y + 0.5) * sy - 0.5

    def cov_to_camera(self, cov: tuple[float, float, float]) -> tuple[float, float, float]:
        """A covariance (var x, var y, cov xy) in working px^2 in camera px^2."""
        sx, sy = self.scale
        return cov[0] / (sx * sx), cov[1] / (sy * sy), cov[2] / (sx * sy)

    def light_grid(self) -> LightGrid | None:
        """(frame size, box): the camera frame scaled by the working scale and the ROI in it, so that a light predictor
        built for that frame size over that box yields one value per working pixel, centred where :meth:`to_camera`
        puts it; None when the scaled frame or ROI is not whole pixels (the light is then predicted at the camera's
        size and area-averaged by :meth:`cut_roi`)."""
        sx, sy = self.scale
        fw, fh = self.frame_size
        x, y, _, _ = self.roi
        scaled = (fw * sx, fh * sy, x * sx, y * sy)
        if any(abs(v - round(v)) > 1e-6 for v in scaled):
            return None
        sw, sh, bx, by = (int(round(v)) for v in scaled)
        return (sw, sh), (bx, by, self.work_size[0], self.work_size[1])

    def cut_roi(self, part: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """An ROI-size image at the working resolution, in the working dtype: a new array, or ``out`` (working size
        and dtype) filled with it."""
        w, h = self.roi[2], self.roi[3]
        if (w, h) != self.work_size:
            part = cv2.resize(part, self.work_size, interpolation=cv2.INTER_AREA)
        if out is not None:
            np.copyto(out, part)
            return out
        return part.astype(self.dtype, copy=False) if part.dtype != self.dtype else part.copy()
