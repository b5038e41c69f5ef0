"""Candidate shadows in one smoothed depth map, and each one's fingertip.

A candidate is a connected region of smoothed depth above ``candidate_depth``.
Its fingertip is the sub-pixel centroid of its darkening core: the pixels at
least ``core_fraction`` of the candidate's peak depth, weighted by how far they
rise above that level, so the arm or the soft penumbra trailing behind a
fingertip does not pull the point off the pad.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Candidate:
    """One shadow in working-image coordinates."""

    x: float  # sub-pixel fingertip (core centroid), working pixels
    y: float
    peak: float  # largest smoothed depth in the shadow
    core_depth: float  # mean smoothed depth over the core
    area: int  # working pixels above candidate_depth
    label: int  # component label in this frame's Segmentation
    bbox: tuple[int, int, int, int]  # x, y, w, h in working pixels


@dataclass(frozen=True)
class Segmentation:
    """Component labels of one frame, computed only inside the bounding box of the mask (for speed)."""

    labels: np.ndarray  # int32 labels of the box
    offset: tuple[int, int]  # (x, y) of the box in the working image

    def mask_of(self, wanted: list[int], shape: tuple[int, ...]) -> np.ndarray:
        """Full-size bool mask of the pixels of the ``wanted`` components."""
        out = np.zeros(shape, bool)
        x, y = self.offset
        h, w = self.labels.shape
        box = out[y : y + h, x : x + w]
        for label in wanted:
            box |= self.labels == label
        return out


def find_candidates(
    depth: np.ndarray,
    *,
    threshold: float,
    min_area: int,
    core_fraction: float,
    max_candidates: int,
) -> tuple[list[Candidate], Segmentation | None]:
    """Candidates (largest first, working-image coordinates) and their segmentation (None when none)."""
    full_mask = (depth > threshold).view(np.uint8)
    bx, by, bw, bh = cv2.boundingRect(full_mask)
    if bw == 0 or bh == 0:
        return [], None
    mask = full_mask[by : by + bh, bx : bx + bw]
    depth = depth[by : by + bh, bx : bx + bw]
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8, ltype=cv2.CV_32S)
    areas = stats[1:, cv2.CC_STAT_AREA]
    order = np.argsort(-areas, kind="stable")
    found: list[Candidate] = []
    for index in order[:max_candidates]:
        area = int(areas[index])
        if area < min_area:
            break
        label = int(index) + 1
        x0, y0, w, h = (int(v) for v in stats[label, :4])
        patch = depth[y0 : y0 + h, x0 : x0 + w]
        inside = labels[y0 : y0 + h, x0 : x0 + w] == label
        values = np.where(inside, patch, 0.0)
        peak = float(values.max())
        level = core_fraction * peak
        weights = values - level
        np.maximum(weights, 0.0, out=weights)
        total = float(weights.sum())
        core = weights > 0
        if total <= 0.0 or not np.isfinite(total):
            # A flat core (e.g. saturated depth 1.0 everywhere): fall back to the plain core centroid.
            core = values >= level
            weights = core.astype(depth.dtype)
            total = float(weights.sum())
        ys, xs = np.nonzero(core)
        w_core = weights[ys, xs]
        cx = bx + x0 + float(np.dot(xs, w_core)) / total
        cy = by + y0 + float(np.dot(ys, w_core)) / total
        core_depth = float(values[core].mean())
        found.append(Candidate(cx, cy, peak, core_depth, area, label, (bx + x0, by + y0, w, h)))
    return found, Segmentation(labels, (bx, by))
