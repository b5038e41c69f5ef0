"""Replay of recordings (format v1) as a camera: the same frames and timestamps the blimp saw.

A path may be one recording or a dataset; recordings play one after another,
each a new ``segment``. Times are shifted so they keep increasing across
recordings and loops. ``realtime`` replays sleep to the recordings' own
pace and stamp each frame with the time it was due on ``clock`` (the
daemon's, so a replaying daemon's API times mean what a live one's do);
otherwise frames come as fast as the consumer asks (nothing dropped), on
the recordings' clock.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path

from feelium.cameras.base import ClosableReader, Frame
from feelium.recording import Recording, find_recordings


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
    ) -> None:
        if not str(path):
            raise ValueError("the replay backend needs a recording path (rear_camera.replay_path or --replay PATH)")
        self.paths = find_recordings(path)
        self.recordings = [Recording(p) for p in self.paths]  # validates every recording before the first frame
        self.realtime = realtime
        self.loop = loop
        self._gray = gray
        self._clock = clock
        self._sleep = sleep
        self._frames = self._generate()
        self._guard = ClosableReader()

    def _generate(self) -> Iterator[Frame]:
        offset = 0.0
        segment = 0
        wall_start: float | None = None
        while True:
            for recording in self.recordings:
                ts = recording.timestamps
                if len(ts) == 0:
                    continue
                period = float(ts[-1] - ts[0]) / max(len(ts) - 1, 1) if len(ts) > 1 else 1.0 / recording.meta.camera.fps
                shift = offset - float(ts[0]) if segment else 0.0  # the first recording keeps its own clock
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
                    yield Frame(t=stamp, image=image, segment=segment, roi=recording.meta.roi)
                offset = float(ts[-1]) + shift + period
                segment += 1
            if not self.loop:
                return

    def read(self) -> Frame | None:
        with self._guard:
            if self._guard.closed:
                return None
            return next(self._frames, None)

    def close(self) -> None:
        self._guard.close(self._frames.close)
