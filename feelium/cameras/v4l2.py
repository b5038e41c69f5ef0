"""A USB (UVC) front camera through OpenCV's V4L2 backend: its own MJPEG forwarded, else BGR frames."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2

from feelium.cameras.base import CameraUnavailable, ClosableReader, Frame, Jpeg

log = logging.getLogger(__name__)

SYSFS = Path("/sys/class/video4linux")
MJPG = cv2.VideoWriter_fourcc(*"MJPG")  # V4L2_PIX_FMT_MJPEG: the same four characters


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


def open_v4l2(device: str) -> Any:
    """OpenCV's capture of ``device`` through its V4L2 backend (tests pass a stand-in)."""
    return cv2.VideoCapture(device, cv2.CAP_V4L2)


def _fourcc_text(code: float) -> str:
    """A FOURCC as OpenCV returns it (a float) in its four characters, for the log: ``YUYV``, ``MJPG``."""
    value = int(code)
    return "".join(chr(value >> shift & 0xFF) for shift in (0, 8, 16, 24)).strip("\0") or "none"


class V4l2Camera:
    """A V4L2 device's frames, stamped on the monotonic clock when they are handed over: the camera's own MJPEG
    as :class:`Jpeg` (``jpeg`` ``auto`` or ``hardware``), else BGR frames for the daemon to encode.

    Why MJPEG: UVC cameras compress in their own hardware, and the front frames only go to the headset, as JPEG.
    Asking OpenCV for BGR made it decode each frame on the board's ARM cores, and the daemon then encoded it
    again: two codecs per frame where none is needed. With ``CAP_PROP_CONVERT_RGB`` off, OpenCV's V4L2 backend
    hands over the driver's buffer as it is (one row of ``uint8``: the JPEG's bytes). The front camera service
    inserts the Huffman tables UVC frames often leave out (:mod:`feelium.cameras.mjpeg`) before forwarding.
    """

    name = "v4l2"
    realtime = True

    def __init__(
        self, device: str, width: int, height: int, fps: float, jpeg: str = "software",
        clock: Callable[[], float] = time.monotonic, capture: Callable[[str], Any] = open_v4l2,
    ) -> None:  # fmt: skip
        if jpeg not in ("auto", "hardware", "software"):
            raise ValueError(f"jpeg must be 'auto', 'hardware' or 'software', got {jpeg!r}")
        if not Path(device).exists():
            raise CameraUnavailable(f"{device} does not exist: plug in the USB camera or set front_camera.device")
        self._capture = capture(device)
        if not self._capture.isOpened():
            raise CameraUnavailable(f"cannot open {device}: is the user in the 'video' group, or is it busy?")
        self._capture.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        self._capture.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        self._capture.set(cv2.CAP_PROP_FPS, fps)
        self._capture.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # newest frame, not a queue of stale ones
        self._size = (width, height)
        self.jpeg = "software" if jpeg == "software" else self._ask_for_mjpeg(device, jpeg)
        self._clock = clock  # the daemon's (monotonic): frames are stamped on the clock the API gives
        self._guard = ClosableReader()

    def _ask_for_mjpeg(self, device: str, jpeg: str) -> str:
        """``hardware`` when the camera delivers MJPEG at the configured size, untouched by OpenCV; otherwise the
        capture is put back as it was and ``auto`` goes on in ``software`` (one log line), ``hardware`` fails."""
        before = self._capture.get(cv2.CAP_PROP_FOURCC)
        problem = self._mjpeg_problem()
        if problem is None:
            return "hardware"
        self._capture.set(cv2.CAP_PROP_CONVERT_RGB, 1)
        self._capture.set(cv2.CAP_PROP_FOURCC, before)
        if jpeg == "hardware":
            self._capture.release()
            raise CameraUnavailable(f"front camera {device}: {problem}; set front_camera.jpeg = \"software\"")
        log.info("front camera %s: %s; the daemon encodes its JPEGs in software", device, problem)
        return "software"

    def _mjpeg_problem(self) -> str | None:
        """Why the camera's MJPEG cannot be forwarded as it is, or ``None`` once it is set up to be."""
        if not self._capture.set(cv2.CAP_PROP_FOURCC, MJPG) or int(self._capture.get(cv2.CAP_PROP_FOURCC)) != MJPG:
            return f"the camera offers no MJPEG (it delivers {_fourcc_text(self._capture.get(cv2.CAP_PROP_FOURCC))})"
        size = (int(self._capture.get(cv2.CAP_PROP_FRAME_WIDTH)), int(self._capture.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if size != self._size:
            return f"its MJPEG comes at {size[0]}x{size[1]}, not the configured {self._size[0]}x{self._size[1]}"
        if not self._capture.set(cv2.CAP_PROP_CONVERT_RGB, 0) or self._capture.get(cv2.CAP_PROP_CONVERT_RGB) != 0:
            return "OpenCV's V4L2 backend here would not hand over the MJPEG undecoded (CAP_PROP_CONVERT_RGB)"
        return None

    def read(self) -> Frame | None:
        with self._guard:
            if self._guard.closed:
                return None
            ok, image = self._capture.read()
            if not ok:
                raise OSError("the V4L2 camera stopped delivering frames (unplugged?)")
            t = self._clock()
            if self.jpeg == "hardware":  # the driver's buffer: one row of the JPEG's bytes
                return Frame(t=t, image=Jpeg(image.tobytes(), *self._size))
            if (image.shape[1], image.shape[0]) != self._size:
                image = cv2.resize(image, self._size, interpolation=cv2.INTER_AREA)
            return Frame(t=t, image=image)

    def close(self) -> None:
        self._guard.close(self._capture.release)
