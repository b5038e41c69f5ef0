"""The camera seam: one small Protocol every frame source implements.

A service calls :meth:`Camera.read` from a worker thread (it blocks until the
next frame), so the event loop never waits on a sensor. Backends own their
device and their clock; everything downstream only sees ``(t, image)``.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

Roi = tuple[int, int, int, int]


class CameraUnavailable(RuntimeError):
    """A backend cannot start: a library, a device or a permission is missing (one line, says what to do)."""


@dataclass(frozen=True)
class Jpeg:
    """A frame the camera's own encoder already compressed: the Pi's VideoCore (picamera2) or a USB camera's MJPEG.

    Why: the front camera's frames go only to the headset, as JPEG. Encoding them in software costs the board's
    ARM cores a few milliseconds a frame; the camera's encoder costs them almost nothing. The daemon forwards
    these bytes without decoding them (with the standard Huffman tables inserted when a USB camera left them
    out: :mod:`feelium.cameras.mjpeg`).
    """

    data: bytes
    width: int
    height: int


@dataclass(frozen=True)
class Frame:
    """One captured frame.

    ``t`` is the capture time in seconds on the camera's own clock (strictly
    increasing within a ``segment``); ``segment`` changes when the source
    jumps (a replay moves to its next recording or loops), so consumers can
    reset what they learned about the scene; ``roi`` is the sensitive patch in
    this frame's pixels (``None`` = whole frame).

    A replayed recording that carries its projector stream says so in
    ``stream``, and each frame brings the projector frames ``shown`` since the
    previous one (``(t, frame)``, display times on the same clock as ``t``):
    what lit the membrane the replayed camera saw, which the live projector's
    output is not.
    """

    t: float
    image: np.ndarray | Jpeg  # a Jpeg only from a front camera that encodes its frames itself
    segment: int = 0
    roi: Roi | None = None
    stream: ProjectorStream | None = None
    shown: tuple[tuple[float, np.ndarray], ...] = ()


@dataclass(frozen=True)
class ProjectorStream:
    """The projector stream of a replayed recording: where it is and the projector map found for it."""

    recording: Path
    calibration: Path | None  # a saved map or a calibration recording (feelium.recording.find_calibration); None: none


@runtime_checkable
class Camera(Protocol):
    """A source of timestamped frames.

    ``realtime`` sources deliver at their own pace whether or not anyone keeps
    up (a slow consumer drops frames); other sources (a replay run as fast as
    possible) deliver only when asked, so nothing is dropped.
    """

    name: str
    realtime: bool

    def read(self) -> Frame | None:
        """Block until the next frame; ``None`` when the source has ended for good."""
        ...

    def close(self) -> None:
        """Release the device; safe to call twice and while a read is in flight."""
        ...


class Pacer:
    """Sleeps a reading thread until each frame's due time, at a fixed rate on a monotonic clock.

    When the reader falls behind by more than a frame, the schedule restarts
    from now instead of bursting to catch up (a real sensor drops frames too).
    """

    def __init__(self, fps: float, clock=time.monotonic, sleep=time.sleep) -> None:
        if fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self.period = 1.0 / fps
        self._clock = clock
        self._sleep = sleep
        self._next: float | None = None
        self.late = 0

    def wait(self) -> float:
        """Sleep until the next frame is due and return the clock time it was due at."""
        now = self._clock()
        if self._next is None:
            self._next = now
        elif now > self._next + self.period:
            self.late += 1
            self._next = now
        elif now < self._next:
            self._sleep(self._next - now)
        due = self._next
        self._next += self.period
        return due


class ClosableReader:
    """Makes ``close()`` wait for an in-flight ``read()`` so a device is never released under a reader."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.closed = False

    def __enter__(self) -> "ClosableReader":
        self._lock.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self._lock.release()

    def close(self, release) -> None:
        with self._lock:
            if not self.closed:
                self.closed = True
                release()
