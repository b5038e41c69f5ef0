"""``feelium record``: the live rear camera to a recording (format v1), so the blimp collects real data.

Frames keep the camera's own timestamps (the spec forbids synthesising them
on a device). The writer is atomic: a recording cut by a crash never looks
whole, while the time limit, a stop request (Ctrl-C, SIGTERM, SIGHUP: see
:func:`stop_on_signals`) or a nearly full disk finish a valid, shorter take.

Thermal seam: a :class:`ThermalCapture` (the thermal package's MLX90640
reader, once it offers one) is sampled on the camera clock and its frames go
into ``thermal.npz``; until then recordings hold the camera only.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import math
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from feelium.cameras.base import Camera
from feelium.recording import DiskFull, RecordingWriter, ThermalData

log = logging.getLogger(__name__)


class ThermalCapture(Protocol):
    """Collects thermal frames on the rear camera's clock while it records."""

    fps: float

    def sample(self, t: float) -> None:
        """Called after every camera frame at camera time ``t``; reads a thermal frame when one is due."""
        ...

    def result(self) -> ThermalData | None:
        """Everything captured, or ``None`` when nothing was."""
        ...


@dataclass(frozen=True)
class Take:
    """A finished recording and why it ended: ``"time limit"``, ``"source ended"``, ``"stopped"`` or ``"disk full"``."""

    path: Path
    frames: int
    seconds: float
    ended: str
    problem: str = ""  # the disk's one-line complaint when ``ended == "disk full"``


STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event, signals: tuple[signal.Signals, ...] = STOP_SIGNALS) -> Iterator[list[str]]:
    """While inside, each of ``signals`` sets ``stop`` (the take is finished) instead of killing the process.

    ``systemctl stop``, a closed SSH session (SIGHUP) and Ctrl-C all mean "enough", never "throw it away".
    Yields a list that receives the names of the signals that arrived. Main thread only.
    """
    caught: list[str] = []

    def handler(signum: int, _frame: Any) -> None:
        caught.append(signal.Signals(signum).name)
        stop.set()

    previous = {sig: signal.signal(sig, handler) for sig in signals}
    try:
        yield caught
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def record(
    camera: Camera,
    out: Path,
    *,
    seconds: float | None,
    fps: float,
    name: str,
    session: str = "",
    source: str = "device",
    extra_meta: dict[str, Any] | None = None,
    thermal: ThermalCapture | None = None,
    stop: threading.Event | None = None,
    on_frame: Callable[[int, float], None] | None = None,
    writer_options: dict[str, Any] | None = None,
) -> Take:
    """Record frames until ``seconds`` of camera time have passed, the source ends, ``stop`` is set or the disk fills.

    ``writer_options`` go to :class:`RecordingWriter` (a test's tiny disk).
    """
    first = camera.read()
    if first is None:
        raise RuntimeError("the rear camera delivered no frame")
    height, width = first.image.shape[:2]
    pixel_format = "gray8" if first.image.ndim == 2 else "bgr8"
    writer = RecordingWriter(
        out,
        name=name,
        width=width,
        height=height,
        fps=fps,
        pixel_format=pixel_format,
        session=session,
        source=source,
        roi=first.roi,
        extra_meta=extra_meta,
        **(writer_options or {}),
    )
    t0 = first.t
    last_t = -math.inf
    frame = first
    ended, problem = "source ended", ""
    try:
        while True:
            t = frame.t - t0
            if t <= last_t:  # a sensor that repeats a timestamp: keep the file valid, drop the frame
                log.warning("dropping a frame whose time %.6f does not advance", t)
            else:
                try:
                    writer.add_frame(t, frame.image)
                except DiskFull as exc:  # the caller reports it, with the take it still gets
                    ended, problem = "disk full", exc.strerror or "disk full"
                    break
                last_t = t
                if thermal is not None:
                    thermal.sample(t)
                if on_frame is not None:
                    try:
                        on_frame(writer.frames_written, t)
                    except Exception as exc:  # progress is a nicety (a hung-up terminal's EIO): never the take's end
                        log.warning("progress stopped (%s); still recording", exc)
                        on_frame = None
            if stop is not None and stop.is_set():
                ended = "stopped"
                break
            frame = camera.read()
            if frame is None:
                break
            if seconds is not None and frame.t - t0 >= seconds:
                ended = "time limit"
                break
    except KeyboardInterrupt:
        ended = "stopped"
        log.info("interrupted: finishing the recording")
    except BaseException:
        writer.abort()
        raise
    if writer.frames_written == 0:  # the disk was full before the first frame: no player or replay accepts an empty take
        writer.abort()
        raise OSError(errno.ENOSPC, problem or "disk full", str(out))
    if thermal is not None and (data := thermal.result()) is not None:
        writer.set_thermal(data, thermal.fps)
    path = writer.close()
    return Take(path, writer.frames_written, max(last_t, 0.0), ended, problem)


def default_name(now: float) -> str:
    """``rec-YYYYmmdd-HHMMSS`` for a wall-clock time."""
    return time.strftime("rec-%Y%m%d-%H%M%S", time.localtime(now))
