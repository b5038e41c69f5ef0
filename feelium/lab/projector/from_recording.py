"""The camera-to-projector map fitted offline from a recording whose projector stream shows structured light.

A real blimp's projector and optics are not the simulator's; what the daemon knows for sure is what it
showed and what the rear camera saw. A calibration recording (``meta.purpose`` ``"projector-calibration"``,
an empty scene, docs/recording-format.md) carries both, so the map is decoded from the recorded projector
frames themselves, whatever the sequence was:

- the projector's latency is measured from the recording first (:mod:`feelium.lab.projector.latency`; the
  config's ``[touch] projector_latency_s`` when the sequence cannot tell it), and kept in the map;
- each distinct projector frame is paired with the mean of the camera frames that saw only it (from its
  display time plus that latency to the next one's, after ``settle_frames``; a frame whose exposure
  integrated a switch saw a mix, and pairs with neither);
- a sequence that is this project's own (``feelium calibrate projector`` on the blimp: Gray-code blocks
  and phase fringes, recognised by comparing the recorded frames with the patterns the config would make)
  is decoded by that decoder, to a fraction of a pixel;
- any other sequence of binary patterns each shown with its inverse (OpenCV's ``GrayCodePattern``, or
  someone's own) is decoded generically: a camera pixel's bits, coarsest pattern first, as far as they are
  seen with contrast, name the projector region that lit it, and the region's centroid is its position.
  Finer stripes than the optics resolve simply end the code early, so the map is as fine as they allowed.
  The photometric response comes from the sequence's flat frames, whatever their order: a flat black and
  a flat white give the black level, two or more flat greys between them the gamma (OpenCV's shadow-mask
  images are a flat white and black; without them neither is measured, and the summary says so).

Both end in the same smoothing and summary as a live calibration (:func:`calibrate.summarise_map`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feelium.lab.projector.calibrate import CalibrationResult, PatternCapture, calibrate, summarise_map
from feelium.lab.projector.graycode import PatternPlan, flat_response, make_patterns, smooth_map
from feelium.lab.projector.latency import LatencyError, LatencyEstimate, coarse_frame, measure_latency
from feelium.projector.config import CalibrationConfig
from feelium.recording import CALIBRATION_PURPOSE, Recording, RecordingError, RecordingWriter
from feelium.skin.projector_map import ProjectorMap
from feelium.touch.settle import exposure_shares

PURPOSE = CALIBRATION_PURPOSE  # meta.purpose of a calibration recording
OUTLIER_MIN_PX = 4.0  # generic decoding: raw points this far (projector px) from the local fit, and
OUTLIER_FACTOR = 5.0  # this many times the typical distance, are misread codes, refitted without


@dataclass(frozen=True)
class Shown:
    """One projector frame as it was on the skin, and what the camera saw of it (mean of its frames)."""

    pattern: np.ndarray  # (H_p, W_p) uint8, as recorded
    image: np.ndarray  # (h, w) float32, camera
    frames: int


def distinct_frames(recording: Recording) -> tuple[list[float], list[np.ndarray]]:
    """The recording's distinct projector frames in order, each with the time it went up: consecutive equal frames
    (a pattern held over several projector refreshes) are one, shown from the first's time."""
    if not recording.has_projector:
        raise RecordingError(recording.path / "projector.mkv", "missing file: a calibration recording needs its projector stream")
    starts: list[float] = []
    patterns: list[np.ndarray] = []
    for t, frame in recording.projector_frames(gray=True):
        if patterns and np.array_equal(frame, patterns[-1]):
            continue
        starts.append(t)
        patterns.append(frame)
    if not patterns:
        raise RecordingError(recording.path / "projector.mkv", "holds no frame")
    return starts, patterns


def shown_patterns(recording: Recording, latency_s: float, settle_frames: int, exposure_s: float = 0.0) -> list[Shown]:
    """Each distinct projector frame of the recording with the mean camera image of the frames that saw it.

    A camera frame at ``t`` saw the projector frame shown last at or before ``t - latency_s``; the first
    ``settle_frames`` of each are left out (the projector and the exposure settling), and so is a frame whose
    exposure (``exposure_s`` centred on ``t``) integrated a switch: it saw a mix of two patterns, not either.
    """
    starts, patterns = distinct_frames(recording)
    sums: list[np.ndarray | None] = [None] * len(patterns)
    counts = [0] * len(patterns)
    seen = [0] * len(patterns)
    order = np.asarray(starts)
    for t, frame in recording.frames(gray=True):
        index = int(np.searchsorted(order, t - latency_s, side="right")) - 1
        if index < 0 or len(exposure_shares(starts, t, exposure_s, latency_s)) > 1:
            continue
        seen[index] += 1
        if seen[index] <= settle_frames:
            continue
        image = frame.astype(np.float32)
        sums[index] = image if sums[index] is None else sums[index] + image
        counts[index] += 1
    shown = [Shown(pattern, total / np.float32(n), n) for pattern, total, n in zip(patterns, sums, counts) if total is not None]
    if not shown:
        raise RecordingError(
            recording.path / "camera_ts.txt",
            f"no projector frame was seen by more than {settle_frames} camera frames (settle_frames): nothing to decode",
        )
    return shown


def camera_exposure(recording: Recording, config_exposure_s: float) -> tuple[float, str]:
    """The camera's exposure the recording was taken with, and where it came from: its meta's
    ``camera.exposure_s`` when it says (the recorder knew), else the config's ``[touch] camera_exposure_s``."""
    stated = recording.meta.camera.exposure_s
    return (config_exposure_s, "config") if stated is None else (stated, "recording meta")


def recording_latency(recording: Recording, config_exposure_s: float) -> LatencyEstimate:
    """The projector's latency measured from the recording (:mod:`feelium.lab.projector.latency`), with the
    camera's exposure from its meta (``camera.exposure_s``) when it says, else ``config_exposure_s``.

    Raises :class:`~feelium.lab.projector.latency.LatencyError` when the sequence cannot tell."""
    starts, _ = distinct_frames(recording)
    exposure, origin = camera_exposure(recording, config_exposure_s)
    times, frames = [], []
    for t, frame in recording.frames(gray=True):
        times.append(t)
        frames.append(coarse_frame(frame, recording.meta.roi))
    if not frames:
        raise RecordingError(recording.path / "camera_ts.txt", "holds no camera frame")
    return measure_latency(np.asarray(starts), np.asarray(times), np.stack(frames), exposure, origin)


def own_plan(shown: list[Shown], config: CalibrationConfig) -> PatternPlan | None:
    """The project's own pattern plan when every one of its patterns is among the recorded frames, else ``None``."""
    h, w = shown[0].pattern.shape
    plan = PatternPlan(w, h, config.block_px, config.phase_period_px, config.phase_steps)
    try:
        wanted = make_patterns(plan)
    except (ValueError, RuntimeError):
        return None
    recorded = {s.pattern.tobytes(): s for s in shown}
    return plan if all(p.image.tobytes() in recorded for p in wanted) else None


def _binary_pairs(shown: list[Shown]) -> list[tuple[Shown, Shown]]:
    """Patterns shown with their exact inverse (two levels, each pixel one or the other), coarsest first."""
    pairs = []
    used: set[int] = set()
    for i, a in enumerate(shown):
        if i in used or np.unique(a.pattern).size != 2:
            continue
        inverse = a.pattern.max() + a.pattern.min() - a.pattern.astype(np.int32)
        for j in range(i + 1, len(shown)):
            if j not in used and np.array_equal(shown[j].pattern, inverse):
                pairs.append((a, shown[j]))
                used |= {i, j}
                break
    def transitions(pair: tuple[Shown, Shown]) -> int:
        bits = pair[0].pattern > pair[0].pattern.min()
        return int(np.count_nonzero(np.diff(bits, axis=0)) + np.count_nonzero(np.diff(bits, axis=1)))

    return sorted(pairs, key=transitions)


def decode_generic(shown: list[Shown], min_contrast: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Projector x, y per camera pixel (NaN where undecoded), the decoded mask, and the number of pairs used.

    A camera pixel's code is its bits (pattern brighter than its inverse) from the coarsest pair on, up to
    the first one it sees with less than ``min_contrast``; its position is the centroid of the projector
    pixels with the same code prefix.
    """
    pairs = _binary_pairs(shown)[:62]  # codes are int64
    if not pairs:
        raise ValueError("the projector stream holds no binary pattern shown with its inverse: nothing to decode")
    h, w = shown[0].image.shape
    ph, pw = shown[0].pattern.shape
    cam_code = np.zeros((h, w), np.int64)
    cam_len = np.zeros((h, w), np.int32)
    open_ = np.ones((h, w), bool)
    proj_code = np.zeros((ph, pw), np.int64)
    proj_codes: list[np.ndarray] = []  # the projector's code after each number of bits
    for a, b in pairs:
        diff = a.image - b.image
        bit = diff > 0
        open_ &= np.abs(diff) >= min_contrast
        cam_code = np.where(open_, (cam_code << 1) | bit, cam_code)
        cam_len += open_
        proj_code = (proj_code << 1) | (a.pattern > a.pattern.min())
        proj_codes.append(proj_code.copy())
    ys, xs = np.mgrid[0:ph, 0:pw]
    out_x = np.full((h, w), np.nan, np.float32)
    out_y = np.full((h, w), np.nan, np.float32)
    for length in range(1, len(pairs) + 1):
        pixels = cam_len == length
        if not pixels.any():
            continue
        codes, inverse = np.unique(proj_codes[length - 1].ravel(), return_inverse=True)
        count = np.bincount(inverse)
        cx = np.bincount(inverse, xs.ravel()) / count
        cy = np.bincount(inverse, ys.ravel()) / count
        wanted = cam_code[pixels]
        at = np.clip(np.searchsorted(codes, wanted), 0, len(codes) - 1)
        found = codes[at] == wanted
        px = np.where(found, cx[at], np.nan)
        py = np.where(found, cy[at], np.nan)
        out_x[pixels] = px
        out_y[pixels] = py
    valid = np.isfinite(out_x) & (cam_len > 0)
    return out_x, out_y, valid, len(pairs)


def flat_frames_response(shown: list[Shown], valid: np.ndarray) -> tuple[float | None, float | None]:
    """Black level and gamma from the flat projector frames among ``shown`` (``None`` for what they cannot give).

    A flat frame is one value everywhere; a flat black (0) and a flat white (255) are needed for any figure
    (the model's two ends), and the greys between them for gamma (:func:`graycode.flat_response`).
    """
    flats = {int(s.pattern.flat[0]): s.image for s in shown if s.pattern.min() == s.pattern.max()}
    if 0 not in flats or 255 not in flats:
        return None, None
    try:
        return flat_response(flats[255], flats[0], flats, valid)
    except ValueError:  # too few lit pixels: the figures would be noise
        return None, None


def calibrate_recording(recording: Recording, config: CalibrationConfig, latency_s: float, exposure_s: float) -> CalibrationResult:
    """The map and its summary from one calibration recording (either decoder, see the module's docstring).

    The projector's latency is measured first (:func:`recording_latency`) and, when the sequence can tell it,
    pairs the camera frames with the patterns and is kept in the map (``latency_s``, ``latency_sigma_s``: what
    replay and eval then use); when it cannot, ``latency_s`` (the config's) pairs them, the map carries no
    latency and the summary says why (``latency.reason``). ``exposure_s``: the config's camera exposure, used
    when the recording's meta does not state its own."""
    measured: LatencyEstimate | None
    try:
        measured = recording_latency(recording, exposure_s)
        timing = measured.summary()
        latency_s = measured.latency_s
    except LatencyError as exc:
        measured, timing = None, {"measured": False, "reason": str(exc), "assumed_ms": round(latency_s * 1e3, 2)}
    exposure = camera_exposure(recording, exposure_s)[0]
    result = _fit_map(recording, config, shown_patterns(recording, latency_s, config.settle_frames, exposure))
    timed = dataclasses.replace(
        result.calibration,
        latency_s=None if measured is None else measured.latency_s,
        latency_sigma_s=None if measured is None else measured.spread_s,
    )
    return CalibrationResult(timed, {**result.summary, "latency": timing})


def _fit_map(recording: Recording, config: CalibrationConfig, shown: list[Shown]) -> CalibrationResult:
    """The map from the recording's shown patterns: the project's own decoder when it is the project's sequence,
    else the generic one."""
    camera_size = (recording.meta.camera.width, recording.meta.camera.height)
    source = f"recording {recording.path.name}"
    plan = own_plan(shown, config)
    if plan is not None:
        by_pattern = {s.pattern.tobytes(): s.image for s in shown}
        captures = {p.name: by_pattern[p.image.tobytes()] for p in make_patterns(plan)}
        result = calibrate(captures, plan, config, camera_size, recording.meta.roi, source)
        return CalibrationResult(result.calibration, {**result.summary, "decoder": "own sequence", "patterns_seen": len(shown)})
    raw_x, raw_y, valid, used = decode_generic(shown, config.min_contrast)
    w, h = camera_size
    roi = recording.meta.roi if recording.meta.roi is not None else (0, 0, w, h)
    x, y, rw, rh = roi
    inside = np.zeros((h, w), bool)
    inside[y : y + rh, x : x + rw] = True
    valid &= inside
    proj_x = smooth_map(raw_x, valid, config.smooth_sigma_px)
    proj_y = smooth_map(raw_y, valid, config.smooth_sigma_px)
    # A coarse bit misread (noise at a stripe's edge) puts a pixel a whole stripe away: drop the points far
    # from their neighbours' fit and fit again without them.
    residual = np.hypot(raw_x - proj_x, raw_y - proj_y)
    typical = float(np.nanmedian(residual[valid])) if valid.any() else 0.0
    keep = valid & (residual <= max(OUTLIER_MIN_PX, OUTLIER_FACTOR * typical))
    if keep.sum() < valid.sum():
        valid = keep
        proj_x = smooth_map(raw_x, valid, config.smooth_sigma_px)
        proj_y = smooth_map(raw_y, valid, config.smooth_sigma_px)
    ph, pw = shown[0].pattern.shape
    black_level, gamma = flat_frames_response(shown, valid)
    calibration = ProjectorMap(camera_size, (pw, ph), roi, proj_x, proj_y, source=source, black_level=black_level, gamma=gamma)
    summary = summarise_map(calibration, raw_x, raw_y, patterns=len(shown))
    return CalibrationResult(calibration, {**summary, "decoder": "generic binary pairs", "pairs_used": used, "patterns_seen": len(shown)})


class RecordingCapture:
    """A pattern capture that also writes what it showed and saw as a calibration recording.

    Wraps the live capture (the blimp's projector and rear camera, or the simulator's), so a calibration
    run leaves the recording to fit again offline, or to judge a new decoder on. Times are the camera's
    (``last_t`` of the wrapped capture); a pattern is stamped just after the newest frame, when it went up.
    """

    def __init__(
        self, inner: PatternCapture, out: Path, projector_size: tuple[int, int], fps: float, session: str = "", source: str = "device"
    ) -> None:
        self._inner = inner
        self.camera_size, self.roi = inner.camera_size, inner.roi
        self._projector_size, self._fps = projector_size, fps
        self._out, self._session, self._source = out, session, source
        self._writer: RecordingWriter | None = None
        self._pending: np.ndarray | None = None
        self._last_t = 0.0

    def show(self, pattern: np.ndarray) -> None:
        self._inner.show(pattern)
        self._pending = pattern

    def capture(self) -> np.ndarray:
        frame = self._inner.capture()
        t = float(self._inner.last_t)  # type: ignore[attr-defined]
        writer = self._writer or self._open(frame)
        if self._pending is not None:
            writer.add_projector_frame(min(t, self._last_t + 1e-3), self._pending)
            self._pending = None
        writer.add_frame(t, frame)
        self._last_t = t
        return frame

    def _open(self, first: np.ndarray) -> RecordingWriter:
        h, w = first.shape[:2]
        writer = RecordingWriter(
            self._out, name=self._out.name, width=w, height=h, fps=self._fps, session=self._session, source=self._source,
            pixel_format="gray8" if first.ndim == 2 else "bgr8", roi=self.roi, extra_meta={"purpose": PURPOSE},
        )  # fmt: skip
        writer.set_projector(*self._projector_size, self._fps)
        self._writer = writer
        return writer

    def close(self) -> Path | None:
        """Finish the recording (atomically, as every recording); ``None`` if nothing was captured."""
        return self._writer.close() if self._writer is not None else None
