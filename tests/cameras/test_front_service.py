"""The front camera service publishes BGR frames for the headset and survives bad frames."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from feelium.cameras.base import Frame, Jpeg
from feelium.cameras.select import CameraSource
from feelium.front_camera.service import FrontCameraService
from feelium.hub import Hub


class ScriptedCamera:
    name = "scripted"
    realtime = True

    def __init__(self, images):
        self.images = list(images)
        self.closed = False
        self.t = 0.0

    def read(self):
        if not self.images:
            return None
        self.t += 0.1
        return Frame(t=self.t, image=self.images.pop(0))

    def close(self):
        self.closed = True


async def test_publishes_bgr_frames_and_skips_others():
    bgr = np.zeros((4, 6, 3), np.uint8)
    camera = ScriptedCamera([bgr, np.zeros((4, 6), np.uint8), bgr, bgr.astype(np.float32)])
    hub = Hub()
    service = FrontCameraService(CameraSource("scripted", lambda: camera), hub)
    await service.run()
    assert hub.front_video.published == 2
    assert hub.front_video.get().t == pytest.approx(0.3)
    health = service.health()
    assert health["frames"] == 2 and health["bad_frames"] == 2 and health["backend"] == "scripted"
    assert health["jpeg_by"] == "daemon"  # BGR frames: the headset stream encodes them
    assert camera.closed


async def test_each_frame_wakes_the_event_loop_at_most_once_and_stop_ends_the_run():
    import asyncio
    import time

    class Endless(ScriptedCamera):
        def read(self):
            time.sleep(0.005)
            self.t += 0.01
            return Frame(t=self.t, image=np.zeros((4, 6, 3), np.uint8))

    camera = Endless([])
    service = FrontCameraService(CameraSource("endless", lambda: camera), Hub())
    task = asyncio.create_task(service.run())
    while service.frames < 5:
        await asyncio.sleep(0.01)
    await service.stop()
    await asyncio.wait_for(task, 2.0)
    health = service.health()
    assert health["frames"] >= health["loop_wakeups"] >= 1 and camera.closed


async def test_jpegs_from_the_cameras_encoder_are_published_as_they_are_and_broken_ones_counted():
    data = cv2.imencode(".jpg", np.zeros((4, 6, 3), np.uint8))[1].tobytes()
    good = Jpeg(data, 6, 4)  # with its Huffman tables, as the VideoCore's: the very object is published
    broken = [Jpeg(b"", 6, 4), Jpeg(b"GIF89a....", 6, 4), Jpeg(data[:-40], 6, 4)]  # nothing, not a JPEG, cut short
    camera = ScriptedCamera([good, *broken, good])
    hub = Hub()
    service = FrontCameraService(CameraSource("scripted", lambda: camera), hub)
    assert service.health()["jpeg_by"] is None  # nothing seen yet
    await service.run()
    assert hub.front_video.published == 2 and hub.front_video.get().value is good
    health = service.health()
    assert health["frames"] == 2 and health["bad_frames"] == 3 and health["jpeg_by"] == "camera"
