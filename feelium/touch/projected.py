"""The projector's light as the rear camera integrated it, for the touch pipeline's ``projected_light``.

The projector service publishes the grey skin canvas of every frame it hands
to the display with the time it did so (``hub.projector_canvas``). The touch
service keeps the last few (:class:`ProjectorHistory`, fed on the event loop)
and, for each camera frame, mixes the predicted light of the frames lit during
its exposure, shifted by the projector's latency, with the spread of that mix
over the latency's uncertainty (:class:`ExposureLight`,
:func:`feelium.touch.settle.predicted_exposure`). Each projector frame is
predicted once, however many camera frames it lights, and a frame the projector
shows again (the same canvas array) is not predicted again.
Data flows one way: the projector never hears from touch.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Callable, Sequence

import cv2
import numpy as np

from feelium.skin.projector_map import ProjectorMap
from feelium.touch.buffers import Scratch
from feelium.touch.config import TouchConfig
from feelium.touch.settle import exposure_shares, predicted_exposure

LATE_S = 0.1  # how long after its exposure a camera frame may still be processed: three frames at 30 fps
# A projector frame's grey canvas to its light over (rows, cols) of the finer box (see ExposureLight.window).
WindowPredictor = Callable[[np.ndarray, slice, slice], np.ndarray]
# The light of several grey canvases mixed with weights, over (rows, cols) of the finer box, in one go.
MixWindowPredictor = Callable[[Sequence[tuple[np.ndarray, float]], slice, slice], np.ndarray]
HISTORY_MAX = 16  # a bound whatever the projector's rate (0.2 MB canvases: 3.1 MB at most; 60 fps needs 11)


def touch_with_latency(touch: TouchConfig, calibration: ProjectorMap) -> TouchConfig:
    """``touch`` with the latency the calibration measured (``feelium calibrate projector`` from a calibration
    recording, :mod:`feelium.lab.projector.latency`), when it did (else ``touch`` as it is): the daemon, replay and
    eval then mix each exposure with the projector's own latency, not the one assumed in ``[touch]``.

    The spread is kept at least the configured ``projector_latency_sigma_s``: that setting also stands for what one
    latency for the whole patch cannot see (a scanning projector lights its rows at different times, half a frame
    apart), so a recording whose switches agreed closely narrows nothing; a wider measured spread widens it."""
    if calibration.latency_s is None:
        return touch
    sigma = max(touch.projector_latency_sigma_s, calibration.latency_sigma_s or 0.0)
    return dataclasses.replace(touch, projector_latency_s=calibration.latency_s, projector_latency_sigma_s=sigma)


def history_window_s(config: TouchConfig, late_s: float = LATE_S) -> float:
    """How far before the newest projector frame a camera frame's exposure can still reach back.

    The exposure centred on ``t`` starts ``camera_exposure_s / 2`` before it, and the light then on the membrane
    was shown ``projector_latency_s`` (up to ``projector_latency_sigma_s`` more) earlier; the frame is processed
    up to ``late_s`` after ``t``. With the defaults 0.015 + 0.033 + 0.0167 + 0.1 = 0.165 s: at the projector's
    30 fps the 5 frames shown in that window and the one before it, 6 in all (the old history kept 12).
    """
    return config.camera_exposure_s / 2.0 + config.projector_latency_s + config.projector_latency_sigma_s + late_s


class ProjectorHistory:
    """The projector's recent grey canvases, oldest first, with the times they were shown (bounded in time and
    count: only what a camera exposure being processed can still have seen)."""

    def __init__(self, window_s: float, keep: int = HISTORY_MAX) -> None:
        """``window_s``: :func:`history_window_s`; ``keep``: at most this many canvases whatever the rate."""
        self._window = window_s
        self._frames: deque[tuple[float, int, np.ndarray]] = deque(maxlen=keep)
        self.recorded = 0

    def record(self, t: float, seq: int, canvas: np.ndarray) -> None:
        """Frame number ``seq`` was handed to the projector at ``t`` (the daemon's clock); times must increase.

        Canvases lit only before the window (their successor was shown before ``t - window_s``) are dropped."""
        if self._frames and t <= self._frames[-1][0]:
            return  # a republished or reordered frame says nothing new
        self._frames.append((t, seq, canvas))
        self.recorded += 1
        while len(self._frames) > 1 and self._frames[1][0] <= t - self._window:
            self._frames.popleft()

    def frames(self) -> list[tuple[float, int, np.ndarray]]:
        """A snapshot (the camera's worker thread reads while the event loop records)."""
        return list(self._frames)


class ExposureLight:
    """Per camera frame size: (light, spread) a camera exposure saw, from the recent projector frames."""

    def __init__(
        self,
        predict: Callable[[np.ndarray, np.ndarray | None], np.ndarray],
        config: TouchConfig,
        window: WindowPredictor | None = None,
        *,
        mixed_window: MixWindowPredictor | None = None,
    ) -> None:
        """``predict(canvas, out)``: a projector frame's grey canvas to its light at the camera frame size (relative
        to the flat grey), written into ``out`` when it is an array of that size (float32) or a new array when it is
        None or not. ``out`` is the light of a frame that left the window: recycling it keeps the daemon from
        mapping and faulting in a new 0.3 MB image per projector frame (allocations from 128 KB are mmapped).

        ``window(canvas, rows, cols)``: the light at a finer size than ``predict``'s, over a window only; with it,
        :meth:`window` gives the last exposure's light there (the touch pipeline's fine pass, ``detect_scale`` < 1).
        ``mixed_window(parts, rows, cols)``, used instead when given: the same for the exposure's frames and weights
        (``parts``: canvas, weight) at once, so a predictor that is linear in the light mixes the canvases first and
        predicts the window once (:meth:`feelium.projector.canvaslight.CanvasLightPredictor.window_of_mix`).
        """
        self._predict = predict
        self._window = window
        self._mixed_window = mixed_window
        self._last: tuple[list[tuple[float, int, np.ndarray]], float] | None = None
        self._latency = config.projector_latency_s
        self._sigma = config.projector_latency_sigma_s
        self._exposure = config.camera_exposure_s
        self._lights: dict[int, np.ndarray] = {}
        # The canvas each light was predicted from: the projector hands the very same array again for every
        # frame in which nothing changed (canvases are never rewritten once published), and its light is the same.
        self._sources: dict[int, np.ndarray] = {}
        self._scratch = Scratch()  # the mixes: the pipeline reads them within the same camera frame
        self._free: list[np.ndarray] = []  # lights of frames no longer in the window, to predict into
        self.predicted = 0

    def __call__(self, frames: list[tuple[float, int, np.ndarray]], t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """For the camera exposure centred on ``t`` (the daemon's clock); ``None`` before any projector frame.

        The two arrays are reused by the next call: use them before asking for another exposure."""
        if not frames:
            self._last = None
            return None
        self._last = (frames, t)
        by_seq = {seq: frame for _, seq, frame in frames}

        def light_of(seq: object) -> np.ndarray:
            assert isinstance(seq, int)
            light = self._lights.get(seq)
            if light is None:
                frame = by_seq[seq]
                same = next((s for s, f in self._sources.items() if f is frame), None)  # the projector showed it again
                if same is not None:
                    light = self._lights[same]
                else:
                    out = self._free.pop() if self._free else None
                    light = self._predict(frame, out).astype(np.float32, copy=False)
                    self.predicted += 1
                self._lights[seq], self._sources[seq] = light, frame
            return light

        result = predicted_exposure(
            [(shown, seq) for shown, seq, _ in frames],
            light_of,
            t,
            exposure_s=self._exposure,
            latency_s=self._latency,
            latency_sigma_s=self._sigma,
            scratch=self._scratch,
        )
        for seq in [s for s in self._lights if s not in by_seq]:
            light = self._lights.pop(seq)
            del self._sources[seq]
            if not any(other is light for other in self._lights.values()):  # a frame shown again shares its light
                self._free.append(light)
        del self._free[2:]  # one or two new frames per camera frame
        return result

    def window(self, rows: slice, cols: slice) -> np.ndarray | None:
        """The last exposure's light (at the assumed latency, as :meth:`__call__` mixed it) at the window
        predictor's size over ``rows``, ``cols`` only (a new float32 array); None without a window predictor or
        before any projector frame.

        Why: the coarse detection pass reads the light at its own size, but the fine pass decides a candidate on the
        working resolution's detail, and the projected light carries as sharp edges as the frame (a face's features
        blurred by ~0.5 camera px): upsampling the coarse light would leave them in the depth. Each frame is predicted
        again in the window (not cached: the window moves with the hand), mixed with the same weights."""
        if (self._window is None and self._mixed_window is None) or self._last is None:
            return None
        frames, t = self._last
        shown = [f[0] for f in frames]
        shares = exposure_shares(shown, t, self._exposure, self._latency)
        if self._mixed_window is not None:
            if not shares:
                return None
            return self._mixed_window([(frames[i][2], w) for i, w in shares], rows, cols).astype(np.float32, copy=False)
        assert self._window is not None
        out: np.ndarray | None = None
        for i, w in shares:
            light = self._window(frames[i][2], rows, cols).astype(np.float32, copy=False)
            if out is None:
                out = np.multiply(light, np.float32(w))
            else:
                cv2.scaleAdd(light, float(w), out, dst=out)
        return out
