"""Presence: a warm body drawing near, seen as a cluster of pixels warmer than the room.

Each frame is compared with a per-pixel ambient baseline. The baseline
follows the room slowly (time constant ``baseline_tau_s``) but freezes where
a body is, so someone who stays is not absorbed into the background. A
connected (8-neighbour) cluster of at least ``min_pixels`` pixels warmer
than the baseline by ``enter_rise_c`` is a body; while one is present its
pixels count down to the lower ``leave_rise_c``. The state changes only after
``enter_frames`` frames with a body or ``leave_frames`` frames without,
so one noisy frame neither announces nor loses anyone.

This never decides touch: it tells the blimp someone is near and where.
Pure: frames and their times in, :class:`~feelium.events.PresenceEvent` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from feelium.events import PresenceEvent
from feelium.thermal.config import PresenceConfig

ROWS, COLS = 24, 32


@dataclass(frozen=True)
class Cluster:
    """One warm body in one frame: centroid in sensor pixels (column, row), size, peak rise."""

    x: float
    y: float
    size: int
    peak_rise_c: float


def bearings(x: float, y: float, fov_deg: tuple[float, float]) -> tuple[float, float]:
    """Azimuth (positive right) and elevation (positive up) of a pixel position, through a pinhole lens."""
    fx = (COLS / 2) / math.tan(math.radians(fov_deg[0]) / 2)
    fy = (ROWS / 2) / math.tan(math.radians(fov_deg[1]) / 2)
    azimuth = math.degrees(math.atan((x + 0.5 - COLS / 2) / fx))
    elevation = math.degrees(math.atan((ROWS / 2 - (y + 0.5)) / fy))
    return azimuth, elevation


def largest_warm_cluster(rise: np.ndarray, threshold: float, min_pixels: int) -> tuple[Cluster | None, np.ndarray]:
    """The warm cluster with the most excess heat, and the mask of every warm pixel."""
    warm = np.nan_to_num(rise, nan=-np.inf) > threshold
    if warm.sum() < min_pixels:
        return None, warm
    count, labels, stats, _ = cv2.connectedComponentsWithStats(warm.astype(np.uint8), connectivity=8)
    best: Cluster | None = None
    best_heat = -1.0
    for label in range(1, count):
        size = int(stats[label, cv2.CC_STAT_AREA])
        if size < min_pixels:
            continue
        rows, cols = np.nonzero(labels == label)
        weights = rise[rows, cols]
        heat = float(weights.sum())
        if heat > best_heat:
            best_heat = heat
            best = Cluster(
                x=float(np.sum(weights * cols) / heat),
                y=float(np.sum(weights * rows) / heat),
                size=size,
                peak_rise_c=float(weights.max()),
            )
    return best, warm


class PresenceDetector:
    """Frames in, approach/update/leave events out (see the module docstring)."""

    def __init__(self, config: PresenceConfig | None = None) -> None:
        self.config = config if config is not None else PresenceConfig()
        self.baseline: np.ndarray | None = None
        self.present = False
        self.cluster: Cluster | None = None
        self.frames = 0
        self.skipped = 0  # frames with the wrong shape or no finite pixel
        self._streak = 0
        self._last_t: float | None = None
        self._last_update_t = -math.inf

    def reset(self) -> None:
        self.__init__(self.config)

    def _event(self, phase: str, t: float, cluster: Cluster) -> PresenceEvent:
        fov = (float(self.config.fov_deg[0]), float(self.config.fov_deg[1]))
        az, el = bearings(cluster.x, cluster.y, fov)
        return PresenceEvent(phase, t, cluster.x, cluster.y, az, el, cluster.size, cluster.peak_rise_c)  # type: ignore[arg-type]

    def step(self, t: float, celsius: np.ndarray) -> list[PresenceEvent]:
        """Feed one frame ((24, 32) degC, NaN where unknown) taken at ``t`` seconds."""
        frame = np.asarray(celsius, dtype=np.float64)
        if frame.shape != (ROWS, COLS) or not np.isfinite(frame).any():
            self.skipped += 1
            return []
        cfg = self.config
        if self.baseline is None:
            # the room as first seen; unknown pixels start at the frame's median
            self.baseline = np.where(np.isfinite(frame), frame, float(np.nanmedian(frame)))
            self._last_t = t
            self.frames += 1
            return []
        dt = max(0.0, t - (self._last_t if self._last_t is not None else t))
        self._last_t = t
        self.frames += 1

        rise = frame - self.baseline
        threshold = cfg.leave_rise_c if self.present else cfg.enter_rise_c
        cluster, _ = largest_warm_cluster(rise, threshold, cfg.min_pixels)

        # adapt the baseline where nothing warm is (a body's surroundings included)
        occupied = np.nan_to_num(rise, nan=0.0) > cfg.leave_rise_c
        occupied = cv2.dilate(occupied.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        alpha = 1.0 - math.exp(-dt / cfg.baseline_tau_s)
        adapt = ~occupied & np.isfinite(frame)
        self.baseline[adapt] += alpha * (frame[adapt] - self.baseline[adapt])

        events: list[PresenceEvent] = []
        seen = cluster is not None
        if seen != self.present:
            self._streak += 1
        else:
            self._streak = 0
        if cluster is not None:
            self.cluster = cluster
        if not self.present and seen and self._streak >= cfg.enter_frames:
            self.present, self._streak = True, 0
            self._last_update_t = t
            events.append(self._event("approach", t, cluster))
        elif self.present and not seen and self._streak >= cfg.leave_frames:
            self.present, self._streak = False, 0
            events.append(self._event("leave", t, self.cluster))
            self.cluster = None
        elif self.present and seen and cfg.update_period_s > 0 and t - self._last_update_t >= cfg.update_period_s:
            self._last_update_t = t
            events.append(self._event("update", t, cluster))
        return events


__all__ = ["Cluster", "PresenceDetector", "bearings", "largest_warm_cluster"]
