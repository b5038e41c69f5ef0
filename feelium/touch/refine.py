"""The fingertips found again at the working resolution, in a window around the shadows a coarser pass found.

Why: with ``[touch] detect_scale`` < 1 the pipeline runs its whole per-pixel work (reference, relative depth,
compensation, noise floor, candidates) on the ROI at that fraction of the working resolution: 4x fewer pixels at
0.5. What the gates read from a candidate is not resolution-free, though: the *contact edge* (the steepest depth
gradient near the core) is softened by the coarser pixels (measured: the paper protocol's hardest positive edge
margin fell from +0.009 to +0.003 and the latency grew by ~20 ms), and the core's centroid is quantised coarser.
So on frames with a candidate, the depth is computed again at the working resolution, only in the window that holds
the candidates' shadows plus the blur's and the edge's reach, and the very same :func:`find_candidates` runs there.

The fine depth needs the frame at the working resolution (cut from the camera frame as the full-resolution path
cuts it) and everything the coarse pass learned, brought up to it: the reference times its gain, the projected
light's response (slope) and the spread's depth bound are all smooth at the coarse pixel's scale (the back-light,
the projector's diffused light, a blurred bound), so a bilinear upsampling of the window loses little the gates
can see, except the membrane's fixed fine texture, which is learned apart (:class:`FineDetail`); what carries the
detail, the frame and the predicted light, is taken at the working resolution (the light predicted in the window
only, :meth:`feelium.touch.projected.ExposureLight.window`). What is left between this and the
full-resolution path is the coarse reference's own adaptation (docs/touch.md, *Detection at half resolution*).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import cv2
import numpy as np

from feelium.touch.buffers import Scratch
from feelium.touch.candidates import Candidate
from feelium.touch.depth import depth_against
from feelium.touch.geometry import WorkingGeometry

Window = tuple[slice, slice]  # rows, columns of the fine working image


def fine_window(
    boxes: list[tuple[int, int, int, int]], coarse: WorkingGeometry, fine: WorkingGeometry, margin: int
) -> Window:
    """The fine working pixels that cover ``boxes`` ([x, y, w, h] in coarse working pixels), plus ``margin``."""
    cw, ch = coarse.work_size
    fw, fh = fine.work_size
    sx, sy = fw / cw, fh / ch
    x0 = min(b[0] for b in boxes)
    y0 = min(b[1] for b in boxes)
    x1 = max(b[0] + b[2] for b in boxes)
    y1 = max(b[1] + b[3] for b in boxes)
    fx0, fy0 = max(int(math.floor(x0 * sx)) - margin, 0), max(int(math.floor(y0 * sy)) - margin, 0)
    fx1, fy1 = min(int(math.ceil(x1 * sx)) + margin, fw), min(int(math.ceil(y1 * sy)) + margin, fh)
    return slice(fy0, fy1), slice(fx0, fx1)


def upsample_window(
    coarse_image: np.ndarray, fine_size: tuple[int, int], window: Window, out: np.ndarray | None = None
) -> np.ndarray:
    """``coarse_image`` bilinearly resampled onto the fine grid (``fine_size`` = width, height), only in ``window``.

    Pixel centres map as :meth:`WorkingGeometry.to_camera` maps them (both grids span the same ROI), so the
    window equals the same window of ``cv2.resize(coarse_image, fine_size, INTER_LINEAR)`` up to rounding. Written
    into ``out`` when given (the window's shape, the image's dtype)."""
    ch, cw = coarse_image.shape[:2]
    sx, sy = cw / fine_size[0], ch / fine_size[1]
    rows, cols = window
    matrix = np.array(
        [[sx, 0.0, (cols.start + 0.5) * sx - 0.5], [0.0, sy, (rows.start + 0.5) * sy - 0.5]], np.float64
    )
    size = (cols.stop - cols.start, rows.stop - rows.start)
    return cv2.warpAffine(
        coarse_image, matrix, size, dst=out, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_REPLICATE,
    )  # fmt: skip


DETAIL_LIMITS = (0.5, 2.0)  # a fine pixel's ratio to its upsampled coarse reference beyond which it is not pattern


class FineDetail:
    """What the flat membrane looks like at the working resolution beyond the coarse reference: per fine pixel, the
    ratio of the flat frame to the coarse reference upsampled (times its gain).

    Why: the back-light holds fixed fine structure (the membrane's texture, the sensor's pixel response, the
    projector's grain) that an area average at the coarse scale cannot hold: measured on the paper protocol's
    sessions, 3.4 % rms (1st-99th percentile 0.91-1.14) between the working-resolution reference and the coarse one
    upsampled. Left out, it is read as depth (a waving hand's fringe measured 0.29 deep where the full-resolution
    path measured 0.20) and as steep edges. The pattern is static, so it is learned slowly and only on one frame
    per ``interval_s``, where the coarse pass saw no shadow; the coarse reference carries everything that changes.
    """

    def __init__(self, *, tau_s: float, interval_s: float) -> None:
        self.tau_s = tau_s
        self.interval_s = interval_s
        self._scratch = Scratch()  # a lesson's temporaries (fine size: allocated anew they would be mmaps each time)
        self.ratio: np.ndarray | None = None
        self._lessons = np.zeros(0, np.float32)  # per fine pixel, how many frames taught it
        self._last_t: float | None = None

    def reset(self) -> None:
        self.ratio = None
        self._lessons = np.zeros(0, np.float32)
        self._last_t = None

    def due(self, t: float) -> bool:
        """Whether the frame at ``t`` teaches the pattern: until a first lesson, then ``interval_s`` after the last
        (a microsecond early counts: frame times are sums of float periods)."""
        return self.ratio is None or self._last_t is None or t - self._last_t >= self.interval_s - 1e-6

    def learn(self, t: float, flat: np.ndarray, expected: np.ndarray, usable: np.ndarray) -> None:
        """Blend ``flat / expected`` (fine size: the frame as the flat membrane lit it, the coarse reference times its
        gain upsampled) into the ratio where ``usable`` (no shadow, not saturated, not dark), by the time since the
        last lesson over ``tau_s``."""
        buf = self._scratch
        ratio = np.maximum(expected, np.float32(1e-3), out=buf.get("detail.lesson", flat.shape, np.float32))
        np.divide(flat, ratio, out=ratio)
        ratio.clip(*DETAIL_LIMITS, out=ratio)
        if self.ratio is None or self.ratio.shape != ratio.shape:
            self.ratio = np.ones(ratio.shape, np.float32)
            self._lessons = np.zeros(ratio.shape, np.float32)
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        decay = np.float32(1.0 - math.exp(-dt / self.tau_s)) if self.tau_s > 0 else np.float32(1.0)
        # The mean of every lesson a pixel had until it has had 1/decay of them, then the exponential average: one
        # frame's noise is not baked into the pattern for a whole time constant.
        self._lessons += usable
        rate = np.maximum(self._lessons, np.float32(1.0), out=buf.like("detail.rate", ratio))
        np.reciprocal(rate, out=rate)
        np.maximum(rate, decay, out=rate)
        step = np.subtract(ratio, self.ratio, out=ratio)
        step *= rate
        # Where not usable the step is 0 (the ratio stays >= DETAIL_LIMITS[0] > 0, so adding +0 keeps its bits): a
        # ufunc's where= ran a masked loop at half this speed over the fine image.
        still = np.logical_not(usable, out=buf.like("detail.still", usable))
        np.copyto(step, np.float32(0.0), where=still)
        self.ratio += step
        self._last_t = t


@dataclasses.dataclass(frozen=True)
class FineInputs:
    """One frame's coarse state the fine depth is built from (coarse working size unless said)."""

    work: np.ndarray  # the frame at the fine working resolution (back-light divided out), fine size
    expected: np.ndarray  # reference times its gain (rows included): what the flat membrane gives this frame
    # The predicted projected light at the fine size over a window (None: nothing projected): the fine pass reads it
    # in its window only, so the daemon predicts it there only (feelium.touch.projected.ExposureLight.window).
    light: Callable[[Window], np.ndarray] | None = None
    slope: np.ndarray | None = None  # the learned response's slope (with ``light``)
    bound: np.ndarray | None = None  # the spread's depth bound, zero where none was computed
    off_face: np.ndarray | None = None  # fine pixels off the face (no signal), fine size
    detail: np.ndarray | None = None  # the flat membrane's fine pattern (:class:`FineDetail`), fine size


def fine_flat(inputs: FineInputs, window: Window, *, saturation_level: float, scratch: Scratch) -> np.ndarray:
    """The fine frame in ``window`` as the flat grey would have lit it (``frame + a * (1 - light)``, saturated pixels
    kept saturated), or the frame itself when nothing is projected."""
    work = inputs.work[window]
    if inputs.light is None or inputs.slope is None:
        return work
    h, w = inputs.work.shape
    slope = upsample_window(inputs.slope, (w, h), window, scratch.like("fine.slope", work))
    part = np.subtract(np.float32(1.0), inputs.light(window), out=scratch.like("fine.part", work))
    part *= slope
    compensated = np.add(work, part, out=part)
    saturated = np.greater_equal(work, saturation_level, out=scratch.like("fine.saturated", work, bool))
    np.copyto(compensated, np.float32(saturation_level), where=saturated)
    return compensated


def fine_expected(inputs: FineInputs, window: Window, scratch: Scratch) -> np.ndarray:
    """What the flat membrane gives each fine pixel of ``window`` this frame: the coarse reference upsampled, times
    the fine pattern once one is learned."""
    h, w = inputs.work.shape
    expected = upsample_window(inputs.expected, (w, h), window, scratch.like("fine.expected_up", inputs.work[window]))
    if inputs.detail is not None:
        expected *= inputs.detail[window]
    return expected


def fine_depth(
    inputs: FineInputs,
    window: Window,
    *,
    sigma: float,
    dark_level: float,
    saturation_level: float,
    scratch: Scratch,
) -> np.ndarray:
    """Smoothed relative depth of the fine working image in ``window``, as the coarse pass computes it: compensated
    for the projected light, masked where dark or saturated, blurred, less the spread's bound, never negative."""
    h, w = inputs.work.shape
    size = (w, h)
    work = fine_flat(inputs, window, saturation_level=saturation_level, scratch=scratch)
    expected = fine_expected(inputs, window, scratch)
    depth = depth_against(
        work, expected, dark_level=dark_level, saturation_level=saturation_level, signed=True, scratch=scratch
    )
    if inputs.off_face is not None:
        depth[inputs.off_face[window]] = 0.0
    smooth = depth
    if sigma > 0.2:
        smooth = cv2.GaussianBlur(
            depth, (0, 0), sigma, dst=scratch.like("fine.smooth", depth), borderType=cv2.BORDER_REPLICATE
        )
    if inputs.bound is not None:
        smooth -= upsample_window(inputs.bound, size, window, scratch.like("fine.bound", smooth))
    np.maximum(smooth, 0.0, out=smooth)
    return smooth


def shifted(candidate: Candidate, window: Window) -> Candidate:
    """A candidate found in ``window`` in the coordinates of the whole fine working image."""
    dx, dy = window[1].start, window[0].start
    x, y, w, h = candidate.bbox
    core = candidate.core_point
    return dataclasses.replace(
        candidate, x=candidate.x + dx, y=candidate.y + dy, bbox=(x + dx, y + dy, w, h),
        core_point=None if core is None else (core[0] + dx, core[1] + dy),
    )  # fmt: skip
