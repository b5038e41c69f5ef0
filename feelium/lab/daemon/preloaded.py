"""Cameras that replay frames decoded once before the run, so the bench measures the daemon and not a decoder.

On the blimp a camera hands over frames the ISP already produced (at the touch
pipeline's working size for the rear camera); its cost in the daemon's process
is close to nothing. A replay that decodes video, or the simulator that renders
each scene, would charge the daemon for work it never does on the Pi. These
frames are rendered by the simulator (the same scenes ``recordings/`` holds)
once, kept in memory and played in a loop at a fixed rate; the bench subtracts
their bytes from the process's resident memory because on the Pi they live in
the camera's own buffers.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np

from feelium.cameras.base import Frame, Jpeg, Pacer, Roi
from feelium.cameras.select import CameraSource
from feelium.sim.config import SimConfig


class PreloadedCamera:
    """Plays ``images`` in a loop at ``fps`` on ``clock``; counts the frames its reader fetched too late."""

    name = "preloaded"
    realtime = True

    def __init__(
        self, images: list[np.ndarray] | list[Jpeg], fps: float, roi: Roi | None = None, clock: Callable[[], float] = time.monotonic
    ) -> None:
        if not images:
            raise ValueError("a preloaded camera needs at least one frame")
        self.images = images
        self.roi = roi
        self.pacer = Pacer(fps, clock=clock)
        self.delivered = 0
        self._closed = False

    def read(self) -> Frame | None:
        if self._closed:
            return None
        t = self.pacer.wait()
        image = self.images[self.delivered % len(self.images)]
        self.delivered += 1
        return Frame(t=t, image=image, roi=self.roi)

    def close(self) -> None:
        self._closed = True


@dataclasses.dataclass
class PreloadedSource:
    """A camera source whose every (re)open plays the same frames; keeps the last camera for its late count."""

    images: list[np.ndarray] | list[Jpeg]
    fps: float
    roi: Roi | None = None
    camera: PreloadedCamera | None = None

    def open(self) -> PreloadedCamera:
        self.camera = PreloadedCamera(self.images, self.fps, self.roi)
        return self.camera

    def source(self) -> CameraSource:
        return CameraSource("preloaded", self.open)

    @property
    def nbytes(self) -> int:
        return sum(len(image.data) if isinstance(image, Jpeg) else image.nbytes for image in self.images)

    @property
    def late(self) -> int:
        return self.camera.pacer.late if self.camera is not None else 0


def rear_frames(sim: SimConfig, size: tuple[int, int], fps: float, seconds: float) -> tuple[list[np.ndarray], Roi]:
    """``seconds`` of the rear camera's view with touches (autoplay every ~1.5 s), at the pipeline's working size."""
    from feelium.sim.live import LiveRearScene

    scene = LiveRearScene(dataclasses.replace(sim, autoplay_period_s=1.5), width=size[0], height=size[1])
    images = [scene.frame(i / fps) for i in range(max(1, round(seconds * fps)))]
    return images, tuple(int(v) for v in scene.roi)  # type: ignore[return-value]


def front_frames(size: tuple[int, int], fps: float, seconds: float, seed: int) -> list[np.ndarray]:
    """``seconds`` of the simulated fisheye room view (BGR) at the headset's size."""
    from feelium.cameras.sim_front import SimFisheyeRoom

    room = SimFisheyeRoom(size[0], size[1], seed=seed)
    return [room.frame(i / fps) for i in range(max(1, round(seconds * fps)))]


def encoded_once(images: list[np.ndarray], quality: int) -> list[Jpeg]:
    """``images`` as the JPEGs a camera with a hardware encoder hands over (the blimp's front camera with
    ``[front_camera] jpeg`` hardware): encoded here once, before the run, since on the Pi the VideoCore encodes
    them and the ARM cores only pass the bytes on. At the headset stream's own quality, so the bytes sent are
    those the daemon's software encoder would send."""
    from feelium.http.jpeg import encode_jpeg

    return [Jpeg(encode_jpeg(image, quality), int(image.shape[1]), int(image.shape[0])) for image in images]
