"""The front camera service: the fisheye's frames to ``hub.front_video`` for the headset."""

from __future__ import annotations

import logging
from typing import Any

from feelium.cameras.reader import RateMeter, Worker, close_camera, frame_condition
from feelium.cameras.select import CameraSource
from feelium.hub import Hub

log = logging.getLogger(__name__)


class FrontCameraService:
    """Publishes every frame (BGR) the front camera delivers; the ``Latest`` slot makes the newest win."""

    name = "front_camera"
    stop_order = 50

    def __init__(self, source: CameraSource, hub: Hub, stale_after_s: float = 2.0) -> None:
        self.source = source
        self.stale_after_s = stale_after_s
        self.hub = hub
        self.frames = 0
        self.bad_frames = 0
        self.opens = 0
        self.last_frame_at: float | None = None
        self._rate = RateMeter()
        self._stopping = False

    async def run(self) -> None:
        self._stopping = False
        worker = Worker("front-camera")
        try:
            camera = await worker.call(self.source.open)
        except BaseException:
            worker.shutdown()
            raise
        self.opens += 1
        log.info("front camera: %s backend", self.source.backend)
        try:
            while not self._stopping:
                frame = await worker.call(camera.read)
                if frame is None:
                    log.info("front camera: source ended")
                    return
                image = frame.image
                if image.ndim != 3 or image.shape[2] != 3 or image.dtype.name != "uint8":
                    self.bad_frames += 1  # a BGR uint8 frame is what the headset stream encodes
                    continue
                now = self.hub.clock()
                self.hub.front_video.publish(frame.t, image)
                self.frames += 1
                self.last_frame_at = now
                self._rate.tick(now)
        finally:
            await close_camera(camera, worker)

    async def stop(self) -> None:
        self._stopping = True

    def health(self) -> dict[str, Any]:
        now = self.hub.clock()
        return {
            **frame_condition(self.last_frame_at, now, self.stale_after_s, "front camera"),
            "backend": self.source.backend,
            "frames": self.frames,
            "fps": round(self._rate.rate(now), 2),
            "bad_frames": self.bad_frames,
            "opens": self.opens,
            "last_frame_at": self.last_frame_at,
        }
