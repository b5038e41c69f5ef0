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
import queue
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import cv2

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


class ProjectorStream(Protocol):
    """Shows projector frames on its own thread and reports each with the time the display got it
    (:class:`feelium.projector.showloop.ShowLoop`), so the take keeps what lit the membrane."""

    size: tuple[int, int]
    fps: float
    error: BaseException | None

    def start(self, sink: Callable[[float, Any], None]) -> None: ...

    def stop(self) -> None: ...


PROJECTOR_LEAD = 4  # frames shown up to the first camera frame that are kept: they lit its exposure
FIRST_SHOW_S = 2.0  # how long the take waits for the projector's first frame before the camera starts
PROJECTOR_HELD = 8  # at most this many frames wait for the take to start (grey 1280x720: 0.9 MB each)


class _ProjectorSink:
    """Takes the projector's frames from its thread into the take, on the camera's time axis.

    The show starts before the camera's first frame (whose exposure it lights), when the writer and the time
    origin do not exist yet: the last few frames are held (grey, as the stream keeps them) until
    :meth:`attach`, which keeps the last :data:`PROJECTOR_LEAD` shown up to the first frame and every one
    after. A full disk ends the stream (counted, named) while the camera's own frames meet the same reserve
    and end the take.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._held: list[tuple[float, Any]] = []
        self._writer: RecordingWriter | None = None
        self._t0 = 0.0
        self.first_shown = threading.Event()
        self.frames = 0
        self.problem = ""

    def __call__(self, shown_at: float, frame: Any) -> None:
        self.first_shown.set()
        with self._lock:
            if self._writer is None:
                grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame.copy()
                self._held = [*self._held[-(PROJECTOR_HELD - 1):], (shown_at, grey)]
                return
            self._write(shown_at, frame)

    def _write(self, shown_at: float, frame: Any) -> None:
        if self.problem or self._writer is None:
            return
        try:
            self._writer.add_projector_frame(shown_at - self._t0, frame)
            self.frames += 1
        except DiskFull as exc:
            self.problem = f"projector stream cut: {exc.strerror or 'disk full'}"

    def attach(self, writer: RecordingWriter, t0: float) -> None:
        with self._lock:
            self._writer, self._t0 = writer, t0
            before = [item for item in self._held if item[0] <= t0][-PROJECTOR_LEAD:]
            for shown_at, frame in before + [item for item in self._held if item[0] > t0]:
                self._write(shown_at, frame)
            self._held = []

    def detach(self) -> None:
        """No frame reaches the writer after this returns (it is about to be closed)."""
        with self._lock:
            self._writer = None
            self.problem = self.problem or "detached"


@dataclass(frozen=True)
class Take:
    """A finished recording and why it ended: ``"time limit"``, ``"source ended"``, ``"stopped"``, ``"disk full"``
    or ``"camera stalled"``."""

    path: Path
    frames: int
    seconds: float
    ended: str
    problem: str = ""  # the one-line complaint when ``ended`` is ``"disk full"`` or ``"camera stalled"``
    projector_frames: int = 0  # projector frames kept with the take (``projector.mkv``), when it projected
    projector_problem: str = ""  # why the projector stream ended before the take did, if it did


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


STALL_S = 5.0  # no frame for this long ends the take: a camera that stopped delivering is not a recording
_POLL_S = 0.1  # how often a wait for the next frame looks at the stop request


class CameraStalled(RuntimeError):
    """The camera delivered no frame for ``STALL_S`` before the take had a first frame."""


class _FrameFeed:
    """The camera read in a thread of its own, so that a read that never returns (a ``capture_request()``
    with no frame coming) can neither hold up a stop request nor the end of the take.

    The thread is a daemon: when the take ends on a stalled read, the process can still exit.
    """

    _END = object()

    def __init__(self, camera: Camera) -> None:
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=4)  # the writer's back-pressure, as a direct read had
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._read_all, args=(camera,), name="record-camera", daemon=True)
        self._thread.start()

    def _read_all(self, camera: Camera) -> None:
        try:
            while not self._done.is_set() and (frame := camera.read()) is not None:
                self._queue.put(frame)
        except BaseException as exc:  # handed to the recording thread, which decides
            self._queue.put(exc)
            return
        self._queue.put(self._END)

    def close(self, wait_s: float = 1.0) -> None:
        """Stop reading; wait (bounded) for a read in progress, so the caller's ``camera.close()`` does not race
        it. A stalled read is left behind in its daemon thread."""
        self._done.set()
        deadline = time.monotonic() + wait_s
        while self._thread.is_alive() and time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):
                self._queue.get(timeout=0.02)  # a reader blocked on a full queue can then see ``_done``

    def next(self, stop: threading.Event | None, stall_s: float) -> Any:
        """The next frame; ``None`` at the source's end; ``"stopped"`` once ``stop`` is set; ``"stalled"``."""
        waited = 0.0
        while True:
            if stop is not None and stop.is_set():
                self._done.set()  # read no more; what was read already still goes into the take
                try:
                    item = self._queue.get_nowait()
                except queue.Empty:
                    return "stopped"
                return "stopped" if item is self._END or isinstance(item, BaseException) else item
            try:
                item = self._queue.get(timeout=_POLL_S)
            except queue.Empty:
                waited += _POLL_S
                if waited >= stall_s:
                    return "stalled"
                continue
            if item is self._END:
                return None
            if isinstance(item, BaseException):
                raise item
            return item


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
    stall_s: float = STALL_S,
    projector: ProjectorStream | None = None,
    files: dict[str, bytes] | None = None,
) -> Take:
    """Record frames until ``seconds`` of camera time have passed, the source ends, ``stop`` is set, the disk
    fills or the camera delivers nothing for ``stall_s`` (``ended == "camera stalled"``: what came before is kept).

    ``projector``: shown while recording, each frame kept in the take with the time it was shown, on the
    camera's clock (the stream's clock must be the camera's). ``files``: more files to keep in the take (the
    projector calibration its replay needs). ``writer_options`` go to :class:`RecordingWriter` (a test's tiny
    disk).
    """
    sink = _ProjectorSink() if projector is not None else None
    if projector is not None and sink is not None:
        projector.start(sink)
        # the camera starts once something is shown, so the first exposure is lit by a frame the take keeps
        if not sink.first_shown.wait(FIRST_SHOW_S):
            log.warning("the projector showed nothing in %.0f s; recording without its first frames", FIRST_SHOW_S)
    feed = _FrameFeed(camera)
    try:
        take = _record_from(feed, out, seconds=seconds, fps=fps, name=name, session=session, source=source,
                            extra_meta=extra_meta, thermal=thermal, stop=stop, on_frame=on_frame,
                            writer_options=writer_options, stall_s=stall_s, projector=projector, sink=sink,
                            files=files or {})  # fmt: skip
    finally:
        feed.close()
        if projector is not None:
            projector.stop()
    return take


def _record_from(
    feed: _FrameFeed,
    out: Path,
    *,
    seconds: float | None,
    fps: float,
    name: str,
    session: str,
    source: str,
    extra_meta: dict[str, Any] | None,
    thermal: ThermalCapture | None,
    stop: threading.Event | None,
    on_frame: Callable[[int, float], None] | None,
    writer_options: dict[str, Any] | None,
    stall_s: float,
    projector: ProjectorStream | None,
    sink: _ProjectorSink | None,
    files: dict[str, bytes],
) -> Take:
    first = feed.next(stop, stall_s)
    if first in (None, "stopped"):
        raise RuntimeError("the rear camera delivered no frame")
    if first == "stalled":
        raise CameraStalled(f"the rear camera delivered no frame in {stall_s:g} s")
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
        for file_name, data in files.items():
            writer.add_file(file_name, data)
        if projector is not None and sink is not None:
            writer.set_projector(*projector.size, projector.fps)
            sink.attach(writer, t0)
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
            frame = feed.next(stop, stall_s)
            if frame == "stopped":
                ended = "stopped"
                break
            if frame == "stalled":
                ended, problem = "camera stalled", f"the rear camera delivered no frame for {stall_s:g} s"
                break
            if frame is None:
                break
            if seconds is not None and frame.t - t0 >= seconds:
                ended = "time limit"
                break
    except KeyboardInterrupt:
        ended = "stopped"
        log.info("interrupted: finishing the recording")
    except BaseException:
        if sink is not None:
            sink.detach()
        writer.abort()
        raise
    cut = ""
    if sink is not None:
        cut = sink.problem
        sink.detach()
        if projector is not None and projector.error is not None:
            cut = cut or f"projector stream cut: {projector.error}"
    if writer.frames_written == 0:  # the disk was full before the first frame: no player or replay accepts an empty take
        writer.abort()
        raise OSError(errno.ENOSPC, problem or "disk full", str(out))
    if thermal is not None and (data := thermal.result()) is not None:
        writer.set_thermal(data, thermal.fps)
    path = writer.close()
    if writer.frames_lost:  # the disk filled between two frames (another process): the video holds fewer
        ended = "disk full"
        problem = f"{problem or 'disk full'}; the last {writer.frames_lost} frames did not reach the disk"
    projected = writer.projector_frames if sink is not None else 0  # after close's cut to what the video holds
    return Take(path, writer.frames_written, writer.seconds, ended, problem, projected, cut)


def default_name(now: float) -> str:
    """``rec-YYYYmmdd-HHMMSS`` for a wall-clock time."""
    return time.strftime("rec-%Y%m%d-%H%M%S", time.localtime(now))
