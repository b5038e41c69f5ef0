"""The projector's frames as the rear camera integrated them, for the touch pipeline's ``projected_light``.

The projector service publishes every frame it hands to the display with the
time it did so (``hub.projector_video``). The touch service keeps the last few
(:class:`ProjectorHistory`, fed on the event loop) and, for each camera frame,
mixes the predicted light of the frames lit during its exposure, shifted by
the projector's latency, with the spread of that mix over the latency's
uncertainty (:class:`ExposureLight`, :func:`feelium.touch.settle.predicted_exposure`).
Each projector frame is predicted once, however many camera frames it lights, and a frame the projector
shows again (the same array) is not predicted again.
Data flows one way: the projector never hears from touch.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

import numpy as np

from feelium.touch.buffers import Scratch
from feelium.touch.config import TouchConfig
from feelium.touch.settle import predicted_exposure

HISTORY_FRAMES = 12  # 0.4 s at 30 fps: more than the exposure, latency and a late camera frame together


class ProjectorHistory:
    """The projector frames shown lately, oldest first, with the times they were shown (bounded)."""

    def __init__(self, keep: int = HISTORY_FRAMES) -> None:
        self._frames: deque[tuple[float, int, np.ndarray]] = deque(maxlen=keep)
        self.recorded = 0

    def record(self, t: float, seq: int, frame: np.ndarray) -> None:
        """Frame number ``seq`` was handed to the projector at ``t`` (the daemon's clock); times must increase."""
        if self._frames and t <= self._frames[-1][0]:
            return  # a republished or reordered frame says nothing new
        self._frames.append((t, seq, frame))
        self.recorded += 1

    def frames(self) -> list[tuple[float, int, np.ndarray]]:
        """A snapshot (the camera's worker thread reads while the event loop records)."""
        return list(self._frames)


class ExposureLight:
    """Per camera frame size: (light, spread) a camera exposure saw, from the recent projector frames."""

    def __init__(self, predict: Callable[[np.ndarray], np.ndarray], config: TouchConfig) -> None:
        """``predict``: a projector frame to its light at the camera frame size (relative to the flat grey)."""
        self._predict = predict
        self._latency = config.projector_latency_s
        self._sigma = config.projector_latency_sigma_s
        self._exposure = config.camera_exposure_s
        self._lights: dict[int, np.ndarray] = {}
        # The frame each light was predicted from: the projector hands the very same array again for every
        # frame in which nothing changed (frames are never rewritten while held), and its light is the same.
        self._sources: dict[int, np.ndarray] = {}
        self._scratch = Scratch()  # the mixes: the pipeline reads them within the same camera frame
        self.predicted = 0

    def __call__(self, frames: list[tuple[float, int, np.ndarray]], t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """For the camera exposure centred on ``t`` (the daemon's clock); ``None`` before any projector frame.

        The two arrays are reused by the next call: use them before asking for another exposure."""
        if not frames:
            return None
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
                    light = self._predict(frame).astype(np.float32, copy=False)
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
            del self._lights[seq], self._sources[seq]
        return result
