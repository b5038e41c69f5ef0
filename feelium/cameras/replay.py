"""Replay of recordings (format v1) as a camera: the same frames and timestamps the blimp saw.

A path may be one recording or a dataset; recordings play one after another,
each a new ``segment``. A bad recording in a dataset (it fails validation, or
its video ends early) is logged once, naming the file, and left out: the good
ones still play, as ``feelium replay`` and ``eval`` do. Only a path with no
usable recording fails the camera. Times are shifted so they keep increasing across
recordings and loops. ``realtime`` replays sleep to the recordings' own
pace and stamp each frame with the time it was due on ``clock`` (the
daemon's, so a replaying daemon's API times mean what a live one's do);
otherwise frames come as fast as the consumer asks (nothing dropped), on
the recordings' clock.

With ``projector_stream`` (the rear camera's replay), a recording that carries
what the projector showed (``projector.mkv``) brings it along: each frame has
the projector frames shown since the previous one, their display times moved
exactly as the camera's, and names the projector map found for the recording
(``calibration`` if given, else the one beside it:
:func:`feelium.recording.find_calibration`, as ``replay``/``eval`` look).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from feelium.cameras.base import ClosableReader, Frame, ProjectorStream
from feelium.recording import Recording, RecordingError, find_calibration, find_recordings

log = logging.getLogger(__name__)


class ReplayCamera:
    """Frames of one recording or a dataset of them, optionally looping."""

    name = "replay"

    def __init__(
        self,
        path: str | Path,
        *,
        realtime: bool = True,
        loop: bool = False,
        gray: bool = True,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
        projector_stream: bool = False,
        calibration: str | Path | None = None,
    ) -> None:
        if not str(path):
            raise ValueError("the replay backend needs a recording path (rear_camera.replay_path or --replay PATH)")
        self.root = Path(path)
        self.paths = find_recordings(path)
        self.skipped: list[RecordingError] = []
        self.recordings: list[Recording] = []
        for recording_path in self.paths:  # validates every recording before the first frame
            try:
                self.recordings.append(Recording(recording_path))
            except RecordingError as exc:
                self._skip(exc)
        if not self.recordings:
            raise RecordingError(path, f"no usable recording ({len(self.skipped)} skipped: {self.skipped[0]})")
        self.realtime = realtime
        self.loop = loop
        self._gray = gray
        self._clock = clock
        self._sleep = sleep
        self._projector_stream = projector_stream
        self._calibration = Path(calibration) if calibration else None
        self._frames = self._generate()
        self._guard = ClosableReader()

    def _skip(self, problem: RecordingError) -> None:
        self.skipped.append(problem)
        log.warning("replay: skipped %s", problem)

    def _generate(self) -> Iterator[Frame]:
        offset = 0.0
        segment = 0
        wall_start: float | None = None
        while self.recordings:
            for recording in list(self.recordings):
                ts = recording.timestamps
                if len(ts) == 0:
                    continue
                period = float(ts[-1] - ts[0]) / max(len(ts) - 1, 1) if len(ts) > 1 else 1.0 / recording.meta.camera.fps
                shift = offset - float(ts[0]) if segment else 0.0  # the first recording keeps its own clock
                try:
                    stream, shown = self._stream_of(recording)
                    for t, image in recording.frames(gray=self._gray):
                        t_out = t + shift
                        stamp = t_out
                        if self.realtime:
                            now = self._clock()
                            if wall_start is None:
                                wall_start = now - t_out
                            stamp = wall_start + t_out  # when it is due, on the clock: like a live camera's frame
                            if stamp > now:
                                self._sleep(stamp - now)
                        moved = stamp - t  # the projector's display times move as the camera's
                        yield Frame(
                            t=stamp, image=image, segment=segment, roi=recording.meta.roi, stream=stream,
                            shown=tuple((shown_t + moved, projected) for shown_t, projected in shown.until(t)),
                        )  # fmt: skip
                except RecordingError as exc:  # a video ended early: the frames it gave stand, it plays no more
                    self.recordings.remove(recording)
                    self._skip(exc)
                offset = float(ts[-1]) + shift + period
                segment += 1
            if not self.loop:
                return

    def _stream_of(self, recording: Recording) -> tuple[ProjectorStream | None, _Shown]:
        """The recording's projector stream and its frames, when it has one and the stream is asked for."""
        if not (self._projector_stream and recording.has_projector):
            return None, _Shown(iter(()))
        found = self._calibration or find_calibration(recording.path, self.root, recording.meta.session)
        return ProjectorStream(recording.path, found), _Shown(recording.projector_frames(gray=True))

    def read(self) -> Frame | None:
        with self._guard:
            if self._guard.closed:
                return None
            return next(self._frames, None)

    def close(self) -> None:
        self._guard.close(self._frames.close)


class _Shown:
    """A recording's projector frames handed out in display order, up to each camera frame's time."""

    def __init__(self, frames: Iterator[tuple[float, np.ndarray]]) -> None:
        self._frames = frames
        self._next = next(frames, None)

    def until(self, t: float) -> list[tuple[float, np.ndarray]]:
        out = []
        while self._next is not None and self._next[0] <= t:
            out.append(self._next)
            self._next = next(self._frames, None)
        return out
