"""The front camera service: the fisheye's frames to ``hub.front_video`` for the headset.

The camera thread reads and checks frames in one job for the whole run and hands them to the event loop through
a :class:`~feelium.cameras.handoff.LoopInbox`: one loop wake-up per frame (fewer when the loop lags), not a
``run_in_executor`` round trip per read (docs/performance.md).
"""

from __future__ import annotations

import asyncio
import logging
import threading
from dataclasses import replace
from typing import Any

from feelium.cameras.base import Camera, Frame, Jpeg
from feelium.cameras.handoff import LoopInbox
from feelium.cameras.mjpeg import MjpegError, with_huffman_tables
from feelium.cameras.reader import RateMeter, Worker, close_camera, frame_condition
from feelium.cameras.select import CameraSource
from feelium.hub import Hub

log = logging.getLogger(__name__)


class FrontCameraService:
    """Publishes every frame the front camera delivers (BGR, or a :class:`Jpeg` its own encoder made: the
    VideoCore's, a USB camera's MJPEG); the ``Latest`` slot makes the newest win."""

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
        self.jpeg_by: str | None = None  # who encodes the headset's JPEGs: "camera" (its hardware) or "daemon"
        self._rate = RateMeter()
        self._inbox: LoopInbox[Frame | None] | None = None
        self._past_wakeups = 0
        self._ending: threading.Event | None = None
        self._told_bad_jpeg = False

    async def run(self) -> None:
        worker = Worker("front-camera")
        try:
            camera = await worker.call(self.source.open)
        except BaseException:
            worker.shutdown()
            raise
        self.opens += 1
        log.info("front camera: %s backend", self.source.backend)
        ending = self._ending = threading.Event()
        inbox = self._inbox = LoopInbox(asyncio.get_running_loop(), self._publish)
        try:
            if await worker.call(self._read_frames, camera, inbox, ending):
                log.info("front camera: source ended")
        finally:
            ending.set()  # a cancelled run: the read loop ends after its current read, then the camera closes
            inbox.close()
            self._past_wakeups += inbox.wakeups
            self._inbox = None
            await close_camera(camera, worker)

    def _read_frames(self, camera: Camera, inbox: LoopInbox[Frame | None], ending: threading.Event) -> bool:
        """Camera-thread job: read until the source ends (``True``) or the service stops (``False``)."""
        while not ending.is_set():
            frame = camera.read()
            if frame is None:
                return True
            image = frame.image
            if isinstance(image, Jpeg):  # the camera's encoder made it: forwarded, with Huffman tables if it had none
                inbox.post(self._forwardable(frame, image))
            else:  # a BGR uint8 frame is what the headset stream encodes
                ok = image.ndim == 3 and image.shape[2] == 3 and image.dtype.name == "uint8"
                inbox.post(frame if ok else None)
        return False

    def _forwardable(self, frame: Frame, image: Jpeg) -> Frame | None:
        """The frame with Huffman tables a browser can decode, or ``None`` (a bad frame) when it is not a whole JPEG;
        the first such frame is logged with what was wrong (a camera that sends many would flood the log)."""
        try:
            data = with_huffman_tables(image.data)
        except MjpegError as exc:
            if not self._told_bad_jpeg:
                self._told_bad_jpeg = True
                log.warning("front camera: a JPEG from the camera skipped (counted in bad_frames): %s", exc)
            return None
        return frame if data is image.data else replace(frame, image=replace(image, data=data))

    def _publish(self, frames: list[Frame | None]) -> None:
        """On the loop: each good frame of a batch to the hub, in order; the others counted."""
        for frame in frames:
            if frame is None:
                self.bad_frames += 1
                continue
            now = self.hub.clock()
            self.hub.front_video.publish(frame.t, frame.image)
            self.jpeg_by = "camera" if isinstance(frame.image, Jpeg) else "daemon"
            self.frames += 1
            self.last_frame_at = now
            self._rate.tick(now)

    async def stop(self) -> None:
        if self._ending is not None:
            self._ending.set()

    def health(self) -> dict[str, Any]:
        now = self.hub.clock()
        return {
            **frame_condition(self.last_frame_at, now, self.stale_after_s, "front camera"),
            "backend": self.source.backend,
            "frames": self.frames,
            "fps": round(self._rate.rate(now), 2),
            "bad_frames": self.bad_frames,
            "jpeg_by": self.jpeg_by,
            "loop_wakeups": self._past_wakeups + (self._inbox.wakeups if self._inbox is not None else 0),
            "opens": self.opens,
            "last_frame_at": self.last_frame_at,
        }
