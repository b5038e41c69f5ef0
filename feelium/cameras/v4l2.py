"""A USB (UVC) front camera through OpenCV's V4L2 backend."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import cv2

from feelium.cameras.base import CameraUnavailable, ClosableReader, Frame

SYSFS = Path("/sys/class/video4linux")


def usb_camera_devices(sysfs: Path = SYSFS) -> list[str]:
    """Capture nodes of UVC cameras (``/dev/videoN``), skipping the Pi's codec/ISP nodes and UVC metadata nodes."""
    found = []
    if not sysfs.is_dir():
        return found
    for node in sorted(sysfs.glob("video*")):
        driver = node / "device" / "driver"
        try:
            if driver.resolve().name != "uvcvideo":
                continue
            index = (node / "index").read_text().strip() if (node / "index").exists() else "0"
        except OSError:
            continue
        if index == "0":
            found.append(f"/dev/{node.name}")
    return found


class V4l2Camera:
    """BGR frames from a V4L2 device, stamped on the monotonic clock when they are handed over."""

    name = "v4l2"
    realtime = True

    def __init__(
        self, device: str, width: int, height: int, fps: float, clock: Callable[[], float] = time.monotonic
    ) -> None:
        if not Path(device).exists():
            raise CameraUnavailable(f"{device} does not exist: plug in the USB camera or set front_camera.device")
        self._capture = cv2.VideoCapture(device, cv2.CAP_V4L2)
        if not self._capture.isOpened():
            raise CameraUnavailable(f"cannot open {device}: is the user in the 'video' group, or is it busy?")
        self._capture.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        self._capture.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        self._capture.set(cv2.CAP_PROP_FPS, fps)
        self._capture.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # newest frame, not a queue of stale ones
        self._size = (width, height)
        self._clock = clock  # the daemon's (monotonic): frames are stamped on the clock the API gives
        self._guard = ClosableReader()

    def read(self) -> Frame | None:
        with self._guard:
            if self._guard.closed:
                return None
            ok, image = self._capture.read()
            if not ok:
                raise OSError("the V4L2 camera stopped delivering frames (unplugged?)")
            if (image.shape[1], image.shape[0]) != self._size:
                image = cv2.resize(image, self._size, interpolation=cv2.INTER_AREA)
            return Frame(t=self._clock(), image=image)

    def close(self) -> None:
        self._guard.close(self._capture.release)
