"""``feelium record``: the live rear camera to a recording (format v1), so the blimp collects real data.

Frames keep the camera's own timestamps (the spec forbids synthesising them
on a device). The writer is atomic: a recording cut by a crash never looks
whole, while Ctrl-C or the time limit finish it properly.

Thermal seam: a :class:`ThermalCapture` (the thermal package's MLX90640
reader, once it offers one) is sampled on the camera clock and its frames go
into ``thermal.npz``; until then recordings hold the camera only.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from feelium.cameras.base import Camera
from feelium.recording import RecordingWriter, ThermalData

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
) -> Path:
    """Record frames until ``seconds`` of camera time have passed, the source ends or ``stop`` is set."""
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
    )
    t0 = first.t
    last_t = -math.inf
    frame = first
    try:
        while True:
            t = frame.t - t0
            if t <= last_t:  # a sensor that repeats a timestamp: keep the file valid, drop the frame
                log.warning("dropping a frame whose time %.6f does not advance", t)
            else:
                writer.add_frame(t, frame.image)
                last_t = t
                if thermal is not None:
                    thermal.sample(t)
                if on_frame is not None:
                    on_frame(writer.frames_written, t)
            if stop is not None and stop.is_set():
                break
            frame = camera.read()
            if frame is None or (seconds is not None and frame.t - t0 >= seconds):
                break
    except KeyboardInterrupt:
        log.info("interrupted: finishing the recording")
    except BaseException:
        writer.abort()
        raise
    if thermal is not None and (data := thermal.result()) is not None:
        writer.set_thermal(data, thermal.fps)
    return writer.close()


def default_name(now: float) -> str:
    """``rec-YYYYmmdd-HHMMSS`` for a wall-clock time."""
    return time.strftime("rec-%Y%m%d-%H%M%S", time.localtime(now))
