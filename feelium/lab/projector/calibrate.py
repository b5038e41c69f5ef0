"""`feelium calibrate projector`: project the pattern sequence, capture it, decode a dense map.

The capture seam is :class:`PatternCapture` (show a projector image, grab
rear-camera frames); the simulator's :class:`feelium.sim.projection.SimPatternCapture`
implements it with a known warp, the device one with the display backend and
the rear camera. Everything after the captures is pure.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import cv2
import numpy as np

from feelium.skin.projector_map import ProjectorMap, sample
from feelium.projector.config import CalibrationConfig
from feelium.lab.projector.graycode import PatternPlan, decode, make_patterns, photometric, smooth_map


class PatternCapture(Protocol):
    """Shows a pattern on the projector and reads the rear camera."""

    camera_size: tuple[int, int]
    roi: tuple[int, int, int, int] | None

    def show(self, pattern: np.ndarray) -> None: ...

    def capture(self) -> np.ndarray:
        """The next camera frame (gray or BGR uint8) taken after the previous call."""
        ...


@dataclass(frozen=True)
class CalibrationResult:
    calibration: ProjectorMap
    summary: dict[str, Any]


def _as_gray(frame: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame


def capture_sequence(capture: PatternCapture, plan: PatternPlan, config: CalibrationConfig) -> dict[str, np.ndarray]:
    """Show every pattern, skip the settle frames, average the rest: {pattern name: float32 camera image}."""
    images: dict[str, np.ndarray] = {}
    for pattern in make_patterns(plan):
        capture.show(pattern.image)
        for _ in range(config.settle_frames):
            capture.capture()
        acc = None
        for _ in range(config.frames_per_pattern):
            frame = _as_gray(capture.capture()).astype(np.float32)
            acc = frame if acc is None else acc + frame
        assert acc is not None
        images[pattern.name] = acc / np.float32(config.frames_per_pattern)
    return images


def _stats(values: np.ndarray) -> dict[str, float | None]:
    values = values[np.isfinite(values)]
    if values.size == 0:
        return {"median": None, "p95": None, "max": None}
    return {
        "median": round(float(np.median(values)), 4),
        "p95": round(float(np.percentile(values, 95)), 4),
        "max": round(float(values.max()), 4),
    }


def calibrate(
    captures: dict[str, np.ndarray],
    plan: PatternPlan,
    config: CalibrationConfig,
    camera_size: tuple[int, int],
    roi: tuple[int, int, int, int] | None,
    source: str,
) -> CalibrationResult:
    """Decode captured images into a smoothed map over the ROI and summarise its quality.

    ``fit_residual_px``: raw decoded minus smoothed positions (projector px),
    the measurement noise; ``roundtrip_px``: camera -> projector -> camera
    through the fitted inverse the renderer uses (camera px).
    """
    w, h = camera_size
    roi = roi if roi is not None else (0, 0, w, h)
    decoded = decode(captures, plan, config.min_contrast)
    inside = np.zeros((h, w), bool)
    x, y, rw, rh = roi
    inside[y : y + rh, x : x + rw] = True
    valid = decoded.valid & inside
    proj_x = smooth_map(decoded.proj_x, valid, config.smooth_sigma_px)
    proj_y = smooth_map(decoded.proj_y, valid, config.smooth_sigma_px)
    try:
        black_level, gamma = photometric(captures, valid)
    except ValueError:
        black_level = gamma = None
    calibration = ProjectorMap(
        camera_size, (plan.width, plan.height), roi, proj_x, proj_y, source=source, black_level=black_level, gamma=gamma
    )

    summary = summarise_map(calibration, decoded.proj_x, decoded.proj_y, patterns=len(make_patterns(plan)))
    return CalibrationResult(calibration, summary)


def summarise_map(calibration: ProjectorMap, raw_x: np.ndarray, raw_y: np.ndarray, *, patterns: int) -> dict[str, Any]:
    """A fitted map's quality: coverage, the raw decoded positions' distance to the smoothed map (projector px,
    the measurement noise) and the camera -> projector -> camera round trip through the inverse the renderer
    uses (camera px)."""
    w, h = calibration.camera_size
    covered = calibration.covered
    residual = np.hypot(raw_x - calibration.proj_x, raw_y - calibration.proj_y)[covered]
    pw, ph = calibration.projector_size
    summary: dict[str, Any] = {
        "camera": {"width": w, "height": h, "roi": list(calibration.roi)},
        "projector": {"width": pw, "height": ph},
        "patterns": patterns,
        "coverage": round(calibration.coverage(), 4),
        "fit_residual_px": _stats(residual),
        "black_level": None if calibration.black_level is None else round(calibration.black_level, 4),
        "gamma": None if calibration.gamma is None else round(calibration.gamma, 3),
    }
    if covered.sum() >= 50:
        inv_x, inv_y = calibration.projector_to_camera()
        ys, xs = np.nonzero(covered)
        back_x = sample(inv_x, calibration.proj_x[ys, xs], calibration.proj_y[ys, xs])
        back_y = sample(inv_y, calibration.proj_x[ys, xs], calibration.proj_y[ys, xs])
        summary["roundtrip_px"] = _stats(np.hypot(back_x - xs, back_y - ys))
    else:
        summary["roundtrip_px"] = _stats(np.array([]))
    return summary


def truth_error(calibration: ProjectorMap, truth_x: np.ndarray, truth_y: np.ndarray) -> dict[str, float | None]:
    """Distance (projector px) between the recovered map and the true one over the covered area."""
    covered = calibration.covered
    err = np.hypot(calibration.proj_x - truth_x, calibration.proj_y - truth_y)[covered]
    stats = _stats(err)
    stats["within_1px"] = round(float((err <= 1.0).mean()), 5) if err.size else None
    return stats


def run_calibration(capture: PatternCapture, config: CalibrationConfig, projector_size: tuple[int, int], source: str) -> CalibrationResult:
    """The whole procedure: patterns, captures, decoding, summary."""
    plan = PatternPlan(projector_size[0], projector_size[1], config.block_px, config.phase_period_px, config.phase_steps)
    captures = capture_sequence(capture, plan, config)
    return calibrate(captures, plan, config, capture.camera_size, capture.roi, source)
