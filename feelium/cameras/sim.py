"""Simulated cameras: the rear camera renders the live scene simulator, the front one a fisheye room.

Both pace themselves at the configured rate on a monotonic clock and stamp
each frame with the time it was due on the daemon's clock (as the Pi's cameras
do), so a frame's age and a touch's latency mean the same in simulation as on
the blimp; the simulators themselves run on a clock starting near 0.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from feelium.cameras.base import Frame, Pacer, Roi
from feelium.cameras.sim_front import SimFisheyeRoom


class SharedScene:
    """The live rear scene shared by the camera thread and the partner page, on the camera's clock.

    ``hub.rear_scene`` is this object: the HTTP API calls :meth:`press` and
    :meth:`release` with ``hub.clock()`` times on the event loop, the camera
    renders :meth:`frame` from a worker thread; a lock keeps the two apart and
    times are shifted so the scene sees one clock starting near 0.
    """

    def __init__(self, scene: Any, clock: Callable[[], float] = time.monotonic) -> None:
        self.scene = scene
        self._clock = clock
        self.origin = clock()
        self._lock = threading.Lock()

    @property
    def roi(self) -> Roi:
        return tuple(int(v) for v in self.scene.roi)  # type: ignore[return-value]

    def now(self) -> float:
        """The scene's (camera) time now."""
        return self._clock() - self.origin

    def project_probe(self, levels: Any, latency_s: float) -> None:
        """Light the scene with the projector's probe (``levels``: a :class:`feelium.skin.probe.ProbeLevels` fed
        on the daemon's clock), when the scene can show it."""
        if hasattr(self.scene, "project_probe"):
            with self._lock:
                self.scene.project_probe(levels, self.origin, latency_s)

    def press(self, x: float, y: float, t: float, *, hover: bool = False) -> None:
        """Put or move a fingertip at camera pixel (x, y); ``t`` is a ``hub.clock()`` time."""
        with self._lock:
            self.scene.press(x, y, t - self.origin, hover=hover)

    def release(self, t: float) -> None:
        with self._lock:
            self.scene.release(t - self.origin)

    def frame(self, t: float) -> np.ndarray:
        """The scene at camera time ``t``."""
        with self._lock:
            return self.scene.frame(t)


class SimRearCamera:
    """Frames of the live scene simulator at a fixed rate."""

    name = "sim"
    realtime = True

    def __init__(self, scene: SharedScene, fps: float, sleep: Callable[[float], None] = time.sleep) -> None:
        self.scene = scene
        self._pacer = Pacer(fps, clock=scene.now, sleep=sleep)
        self._closed = False

    def read(self) -> Frame | None:
        if self._closed:
            return None
        t = self._pacer.wait()
        return Frame(t=t + self.scene.origin, image=self.scene.frame(t), roi=self.scene.roi)

    def close(self) -> None:
        self._closed = True


class SimFrontCamera:
    """The synthetic fisheye room view at a fixed rate."""

    name = "sim"
    realtime = True

    def __init__(
        self,
        width: int,
        height: int,
        fps: float,
        *,
        seed: int = 1,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self._room = SimFisheyeRoom(width, height, seed=seed)
        self._origin = clock()
        self._pacer = Pacer(fps, clock=lambda: clock() - self._origin, sleep=sleep)
        self._closed = False

    def read(self) -> Frame | None:
        if self._closed:
            return None
        t = self._pacer.wait()
        return Frame(t=t + self._origin, image=self._room.frame(t))

    def close(self) -> None:
        self._closed = True
