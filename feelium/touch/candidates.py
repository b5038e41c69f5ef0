"""Candidate shadows in one smoothed depth map, and each one's fingertip.

A candidate is a connected region of smoothed depth above ``candidate_depth``.
Its fingertip is the sub-pixel centroid of its darkening core: the pixels at
least ``core_fraction`` of the candidate's peak depth, weighted by how far they
rise above that level, so the arm or the soft penumbra trailing behind a
fingertip does not pull the point off the pad.

Each candidate also carries its *edge*: the steepest depth gradient within
``edge_radius`` of its core (a fingertip's pad, or a whole palm pressed flat,
whose edge is far from its centre). Skin pressed on the membrane casts a shadow
as sharp as the membrane's own scatter (and frustrates its reflection, a
sharp extra loss), while a hand even 2 mm above it is blurred by its height,
so the edge tells contact from a close hover where depth alone cannot.

One shadow can hold several contacts (two fingers of one hand, two hands whose
shadows overlap): each separate part of its core is a candidate of its own,
and its *footprint* (the part's shadow at least ``core_fraction`` of its core's
mean depth: a pressed contact's plateau, up to its blurred edge) gives the
contact's area and second moments (:mod:`feelium.touch.shape`).

Where the room's share of the light is known (``room_floor``), the fingertip is
taken only from the part of the core deeper than any hand *above* the membrane
could make it. A finger blocks the room's light along its whole length, and in
a lit room that shadow is nearly as deep as the pad's, so a core at a fraction
of the peak takes in the finger behind the pad and the point slides towards the
wrist; only skin on the membrane takes the projector's own light (the
frustrated reflection), so the part deeper than the room's share is the pad.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from feelium.touch.buffers import Scratch
from feelium.touch.shape import axes_from_moments


@dataclass(frozen=True)
class Candidate:
    """One shadow in working-image coordinates."""

    x: float  # sub-pixel fingertip (core centroid), working pixels
    y: float
    peak: float  # largest smoothed depth in the shadow
    core_depth: float  # mean smoothed depth over the core
    area: int  # working pixels above candidate_depth
    edge: float  # steepest depth gradient near the core, depth per working pixel
    label: int  # component label in this frame's Segmentation
    bbox: tuple[int, int, int, int]  # x, y, w, h in working pixels (of the whole shadow)
    footprint_area: int = 0  # working pixels of the contact's footprint (see find_candidates)
    footprint_cov: tuple[float, float, float] = (0.0, 0.0, 0.0)  # var x, var y, cov xy of the footprint, working px^2
    # The whole core's centroid when the fingertip (x, y) was taken from its part deeper than the room's floor, else
    # None (the same point). The projected gate reads the share there, so the gates are what they were without it.
    core_point: tuple[float, float] | None = None


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
    edge_radius: float = 10.0,
    scratch: Scratch | None = None,
    split_fraction: float = 0.0,
    room_floor: Callable[[float, float], float | None] | None = None,
) -> tuple[list[Candidate], Segmentation | None]:
    """Candidates (largest shadow first, working-image coordinates) and their segmentation (None when none).

    A shadow whose core falls apart into parts between which its depth drops below ``split_fraction`` of the
    core's mean depth (two fingertips of one hand, two hands whose shadows overlap) gives one candidate per part
    of at least ``min_area`` px (the largest part always); the shadow's pixels are shared out to the nearest
    part. 0 never splits. Of two candidates centred on each other's footprint only the deeper is kept.

    ``scratch`` holds the working-size mask (:mod:`feelium.touch.buffers`); nothing returned refers to it. (A caller
    that reads only where the shadows are, the coarse pass of a two-resolution pipeline, takes :func:`shadow_boxes`.)

    ``room_floor(x, y)``: the deepest smoothed depth a hand above the membrane can cast at a point of ``depth``
    (all the light that is not the projector's, :mod:`feelium.touch.roomshare`), None where it is unknown. A core
    deeper than it is localised on that part alone (:func:`_contact_point`); depth, area and edge do not change.
    """
    shadows = _components(depth, threshold, scratch)
    if shadows is None:
        return [], None
    labels, areas, order, (bx, by) = shadows
    full_depth = depth
    depth = depth[by : by + labels.shape[0], bx : bx + labels.shape[1]]
    found: list[Candidate] = []
    for index in order[:max_candidates]:
        area = int(areas[index])
        if area < min_area or len(found) >= max_candidates:
            break
        label = int(index) + 1
        x0, y0, w, h = cv2.boundingRect(np.equal(labels, label).view(np.uint8))
        patch = depth[y0 : y0 + h, x0 : x0 + w]
        inside = labels[y0 : y0 + h, x0 : x0 + w] == label
        values = np.where(inside, patch, 0.0)
        peak = float(values.max())
        level = core_fraction * peak
        weights = values - level
        np.maximum(weights, 0.0, out=weights)
        core = weights > 0
        weight = float(weights.sum())
        if weight <= 0.0 or not math.isfinite(weight):
            # A flat core (e.g. saturated depth 1.0 everywhere): fall back to the plain core centroid.
            core = values >= level
            weights = core.astype(depth.dtype)
        split_level = split_fraction * _mean(values[core])
        for part, owned, part_area in _core_parts(values, core, inside, split_level, min_area):
            part_weights = np.where(part, weights, 0.0)
            total = float(part_weights.sum())
            ys, xs = part.nonzero()
            w_core = part_weights[ys, xs]
            cx = bx + x0 + float(np.dot(xs, w_core)) / total
            cy = by + y0 + float(np.dot(ys, w_core)) / total
            core_point = None
            if room_floor is not None:
                floor = room_floor(cx, cy)
                if floor is not None and floor > level:
                    core_point = (cx, cy)
                    cx, cy = _contact_point(values, part, floor, (bx + x0, by + y0), core_point)
            part_values = values[part]
            part_mean = _mean(part_values)
            # The footprint: where the shadow is at least core_fraction of the core's *mean* depth. The peak of a
            # large flat contact is the largest of many noisy pixels, so a level from it cuts into the plateau.
            footprint = owned & (values >= core_fraction * part_mean)
            fys, fxs = footprint.nonzero()
            x_min, y_min = bx + x0 + int(xs.min()), by + y0 + int(ys.min())
            x_max, y_max = bx + x0 + int(xs.max()), by + y0 + int(ys.max())
            edge = steepest_gradient(full_depth, (x_min, y_min, x_max, y_max), edge_radius)
            found.append(Candidate(
                cx, cy, float(part_values.max()), part_mean, part_area, edge, label,
                (bx + x0, by + y0, w, h), int(fxs.size), _covariance(fxs, fys), core_point,
            ))  # fmt: skip
            if len(found) >= max_candidates:
                break
    return _drop_surrounding(found), Segmentation(labels, (bx, by))


def shadow_boxes(
    depth: np.ndarray, *, threshold: float, min_area: int, max_candidates: int, scratch: Scratch | None = None
) -> list[tuple[int, int, int, int]]:
    """The boxes ([x, y, w, h]) of the shadows :func:`find_candidates` would take candidates from: the components
    above ``threshold`` of at least ``min_area`` px, the ``max_candidates`` largest.

    Why: a two-resolution pipeline's coarse pass reads only where its candidates' shadows are (their boxes:
    :func:`feelium.touch.refine.fine_window`) and finds them again finer, so their fingertips, parts, footprints and
    depths were computed for nothing (~0.1 ms a paced frame, issue 16). The boxes are those of every candidate
    :func:`find_candidates` returns, and possibly more: a shadow whose candidate it drops as surrounding another, or
    that its split parts crowded out of ``max_candidates``, is looked at again finer, where the same rules apply."""
    shadows = _components(depth, threshold, scratch)
    if shadows is None:
        return []
    labels, areas, order, (bx, by) = shadows
    boxes = []
    for index in order[:max_candidates]:
        if int(areas[index]) < min_area:
            break
        x0, y0, w, h = cv2.boundingRect(np.equal(labels, int(index) + 1).view(np.uint8))
        boxes.append((bx + x0, by + y0, w, h))
    return boxes


def _components(
    depth: np.ndarray, threshold: float, scratch: Scratch | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[int, int]] | None:
    """The connected regions of ``depth`` above ``threshold`` (8-connected), labelled inside the bounding box of
    them all: (labels of the box, each label's area (label ``i + 1`` at ``i``), the labels' indices by decreasing
    area, the box's corner (x, y)); None when nothing is above it. ``scratch`` holds the working-size mask."""
    buf = Scratch() if scratch is None else scratch
    full_mask = np.greater(depth, threshold, out=buf.like("candidates.mask", depth, bool)).view(np.uint8)
    bx, by, bw, bh = cv2.boundingRect(full_mask)
    if bw == 0 or bh == 0:
        return None
    mask = full_mask[by : by + bh, bx : bx + bw]
    # Labels only, then areas by bincount and boxes for the few kept: OpenCV's WithStats variant also computes
    # centroids, which made it ~10x slower than the labelling alone (370-515 against 40 us on a 256x192 mask).
    count, labels = cv2.connectedComponents(mask, connectivity=8, ltype=cv2.CV_32S)
    areas = np.bincount(labels.ravel(), minlength=count)[1:]
    return labels, areas, np.argsort(-areas, kind="stable"), (bx, by)


def _contact_point(
    values: np.ndarray, part: np.ndarray, floor: float, origin: tuple[int, int], fallback: tuple[float, float]
) -> tuple[float, float]:
    """The centroid of the ``part`` deeper than ``floor``, weighted by how far each pixel goes below it (``origin``:
    the patch's corner); ``fallback`` when nothing in it is (a hover: all its depth is the room's light)."""
    weights = np.where(part, values - np.float32(floor), 0.0)
    np.maximum(weights, 0.0, out=weights)
    total = float(weights.sum())
    if total <= 0.0 or not math.isfinite(total):
        return fallback
    ys, xs = np.nonzero(weights)
    w = weights[ys, xs]
    return origin[0] + float(np.dot(xs, w)) / total, origin[1] + float(np.dot(ys, w)) / total


def _drop_surrounding(found: list[Candidate]) -> list[Candidate]:
    """Of two candidates centred on each other's footprint, only the deeper one.

    Two contacts cannot share a centre: one of them surrounds the other, like
    the soft shadow of a torso curving away around the patch it presses (a
    ring, split from the patch wherever the shadow dips between them). Skin on
    the membrane is the deeper of the two (it frustrates the membrane's
    reflection), so that one is the contact.
    """
    reach = [0.5 * axes_from_moments(*c.footprint_cov)[0] for c in found]
    out = []
    for i, c in enumerate(found):
        if not any(
            o.core_depth > c.core_depth and math.hypot(o.x - c.x, o.y - c.y) <= max(reach[i], reach[j])
            for j, o in enumerate(found)
        ):
            out.append(c)
    return out


def _core_parts(
    values: np.ndarray, core: np.ndarray, inside: np.ndarray, split_level: float, min_area: int
) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """The core's separate parts (bool masks, largest first), the shadow each one owns (bool mask) and its area.

    Two parts are separate contacts when the shadow between them falls below
    ``split_level``; the shadow's pixels go to the nearest part.
    """
    n, groups = cv2.connectedComponents((values >= split_level).view(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    if n <= 2:
        return [(core, inside, int(np.count_nonzero(inside)))]
    sizes = np.bincount(groups[core], minlength=n)[1:]
    largest = int(np.argmax(sizes))
    keep = [int(i) + 1 for i in np.argsort(-sizes, kind="stable") if sizes[i] >= min_area or i == largest]
    if len(keep) == 1:
        return [(core, inside, int(np.count_nonzero(inside)))]
    seeds = np.ones(core.shape, np.uint8)
    for k in keep:
        seeds[groups == k] = 0
    # Every shadow pixel joins its nearest kept part (one label per connected group of zeros in ``seeds``).
    _, nearest = cv2.distanceTransformWithLabels(seeds, cv2.DIST_L2, 3, labelType=cv2.DIST_LABEL_CCOMP)
    out = []
    for k in keep:
        group = groups == k
        owned = inside & (nearest == int(nearest[group][0]))
        out.append((group & core, owned, int(np.count_nonzero(owned))))
    return out


def _covariance(xs: np.ndarray, ys: np.ndarray) -> tuple[float, float, float]:
    """(var x, var y, cov xy) of pixel centres, each pixel a unit square (+1/12 per axis)."""
    if xs.size == 0:
        return 0.0, 0.0, 0.0
    fx, fy = xs.astype(np.float64), ys.astype(np.float64)
    mx, my = _mean(fx), _mean(fy)
    dx, dy = fx - mx, fy - my
    return float(np.dot(dx, dx) / xs.size + 1 / 12), float(np.dot(dy, dy) / xs.size + 1 / 12), float(np.dot(dx, dy) / xs.size)


def steepest_gradient(depth: np.ndarray, box: tuple[int, int, int, int], radius: float) -> float:
    """Largest gradient magnitude (depth per pixel) of ``depth`` within ``radius`` of ``box`` (x0, y0, x1, y1 inclusive).

    Central differences (Sobel, normalised): the map is already smoothed, so
    one more derivative filter adds little noise. Non-finite values count as 0.
    """
    h, w = depth.shape
    r = max(1, int(math.ceil(radius)))
    x0, y0 = max(box[0] - r, 0), max(box[1] - r, 0)
    x1, y1 = min(box[2] + r + 1, w), min(box[3] + r + 1, h)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return 0.0
    patch = np.ascontiguousarray(depth[y0:y1, x0:x1], dtype=np.float32)
    gx = cv2.Sobel(patch, cv2.CV_32F, 1, 0, ksize=3, scale=0.125, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.Sobel(patch, cv2.CV_32F, 0, 1, ksize=3, scale=0.125, borderType=cv2.BORDER_REPLICATE)
    steepest = float(cv2.magnitude(gx, gy).max())
    return steepest if math.isfinite(steepest) else 0.0



def _mean(values: np.ndarray) -> float:
    """``float(values.mean())`` to the bit (numpy sums in the array's float type, divides in float64 and rounds back
    to that type), NaN when empty. Why: ``ndarray.mean`` runs numpy's Python layer (``_methods._mean``), 3.8 against
    1.5 us on a candidate's few hundred values, and a candidate takes five means (issue 16)."""
    if values.size == 0:
        return math.nan
    return float(values.dtype.type(float(values.sum()) / values.size))
