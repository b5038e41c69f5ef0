"""Shared fixtures: the simulator's fisheye warp as a ground-truth calibration."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from feelium.skin.projector_map import ProjectorMap
from feelium.sim.projection import FisheyeWarp

CAMERA = (640, 480)
ROI = (64, 48, 512, 384)
PROJECTOR = (1280, 720)


@lru_cache(maxsize=1)
def truth_calibration() -> ProjectorMap:
    px, py = FisheyeWarp().truth_map(*CAMERA)
    inside = np.zeros((CAMERA[1], CAMERA[0]), bool)
    x, y, w, h = ROI
    inside[y : y + h, x : x + w] = True
    px[~inside] = np.nan
    py[~inside] = np.nan
    return ProjectorMap(CAMERA, PROJECTOR, ROI, px, py, source="truth")


def centroid(weights: np.ndarray) -> tuple[float, float]:
    ys, xs = np.nonzero(weights > 0)
    w = weights[ys, xs].astype(np.float64)
    return float((xs * w).sum() / w.sum()), float((ys * w).sum() / w.sum())
