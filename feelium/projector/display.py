"""Where projector frames go: the Linux framebuffer on the blimp, or the simulated display (sim) elsewhere.

The blimp has no desktop: the projector is an HDMI display, so its frames are
written straight into ``/dev/fb0`` in the framebuffer's own pixel format,
which the kernel describes in sysfs (``virtual_size``, ``bits_per_pixel``,
``stride``). The sim backend keeps the newest frame, which is also what the
HTTP preview stream shows. A development window (OpenCV's ``imshow``) exists
only where OpenCV was built with a GUI: the headless wheel the project
depends on has none, so there the window backend refuses to start with a
clear message.
"""

from __future__ import annotations

import logging
import mmap
import os
from pathlib import Path
from typing import Protocol, runtime_checkable

import cv2
import numpy as np

log = logging.getLogger(__name__)


class DisplayUnavailable(RuntimeError):
    """A display backend cannot start (device missing, unsupported format): one line saying what to do."""


@runtime_checkable
class Display(Protocol):
    name: str
    frames: int  # frames put on the output (a display may skip one it already shows)

    def show(self, frame: np.ndarray) -> None:
        """Put a BGR uint8 frame on the output (called from a worker thread)."""
        ...

    def close(self) -> None: ...


class SimDisplay:
    """The simulated display: keeps the newest frame and counts them; nothing is shown."""

    name = "sim"

    def __init__(self) -> None:
        self.last: np.ndarray | None = None
        self.frames = 0

    def show(self, frame: np.ndarray) -> None:
        self.last = frame
        self.frames += 1

    def close(self) -> None:
        self.last = None


# Bits per pixel -> OpenCV's conversion from BGR and its bytes per pixel: 16 is little-endian RGB565 (red in the
# high bits), 32 is XRGB8888 (bytes B, G, R, X).
CONVERSIONS = {16: (cv2.COLOR_BGR2BGR565, 2), 32: (cv2.COLOR_BGR2BGRA, 4)}


def _read_sysfs(path: Path) -> str:
    try:
        return path.read_text().strip()
    except OSError as exc:
        raise DisplayUnavailable(f"cannot read {path}: {exc.strerror}; is this a Linux framebuffer device?") from exc


class FbdevDisplay:
    """Writes frames into a Linux framebuffer, letterboxed (scaled to fit, centred) into its virtual size.

    Why mapped: the framebuffer is mapped into memory once, and each frame is converted to the device's pixel
    format by one OpenCV pass straight into the mapping. Converting into a new array, copying it to bytes and
    writing those cost 4.9 ms a 1280x720 frame at 32 bits and 7.4 ms at 16 (numpy's shifts) on the measuring
    machine, against 0.13 ms mapped (session 20, docs/performance.md): at the ~15 changed frames a second
    of a talking face, most of a Pi core at the projection's 6x. The Pi's KMS framebuffer (vc4's fbdev emulation)
    is 16 bits per pixel by default.
    """

    name = "fbdev"

    def __init__(self, device: str = "/dev/fb0", sysfs_root: str = "/sys/class/graphics") -> None:
        dev = Path(device)
        sysfs = Path(sysfs_root) / dev.name
        w, h = (int(v) for v in _read_sysfs(sysfs / "virtual_size").split(","))
        self.bpp = int(_read_sysfs(sysfs / "bits_per_pixel"))
        if self.bpp not in CONVERSIONS:
            raise DisplayUnavailable(f"{device}: {self.bpp} bits per pixel is not supported (16 or 32)")
        self._code, channels = CONVERSIONS[self.bpp]
        stride_file = sysfs / "stride"
        self.stride = int(_read_sysfs(stride_file)) if stride_file.exists() else w * channels
        self.size = (w, h)
        try:
            self._fd = os.open(device, os.O_RDWR)
        except OSError as exc:
            raise DisplayUnavailable(f"cannot open {device}: {exc.strerror} (is the user in the 'video' group?)") from exc
        try:
            self._map = mmap.mmap(self._fd, self.stride * h)
        except (OSError, ValueError) as exc:
            os.close(self._fd)
            raise DisplayUnavailable(f"cannot map {device} ({self.stride * h} bytes for {w}x{h}): {exc}") from exc
        # The visible pixels, row by row at the device's stride: what OpenCV writes into.
        self._pixels: np.ndarray | None = np.ndarray((h, w, channels), np.uint8, self._map, strides=(self.stride, channels, 1))
        self._fitted_from: tuple[int, int] | None = None  # the frame size the letterbox was last cleared for
        self.frames = 0
        self.repeats = 0  # frames not written again: the framebuffer already held them
        self._last: np.ndarray | None = None

    def _target(self, frame: np.ndarray, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The frame as it goes on the device and the part of the device it fills: itself and the whole screen,
        or scaled to fit and centred (the bars cleared once per frame size)."""
        w, h = self.size
        fh, fw = frame.shape[:2]
        if (fw, fh) == (w, h):
            return frame, pixels
        scale = min(w / fw, h / fh)
        nw, nh = max(1, int(fw * scale)), max(1, int(fh * scale))
        if self._fitted_from != (fw, fh):
            pixels[:] = 0
            self._fitted_from = (fw, fh)
            log.warning(
                "projector: frames are %dx%d but the framebuffer is %dx%d: every frame is scaled on the CPU; set the "
                "HDMI mode to the frame size (video= in cmdline.txt, docs/deploy.md)", fw, fh, w, h,
            )
        x0, y0 = (w - nw) // 2, (h - nh) // 2
        shrink = cv2.INTER_AREA if scale < 1.0 else cv2.INTER_LINEAR  # area averaging only pays when shrinking
        return cv2.resize(frame, (nw, nh), interpolation=shrink), pixels[y0 : y0 + nh, x0 : x0 + nw]

    def show(self, frame: np.ndarray) -> None:
        """Convert ``frame`` into the framebuffer, unless it is the very array written last: the framebuffer still
        holds it, and the projector service hands the same array again for every frame in which nothing changed
        (its frames are never written while held). A caller that changes an array in place must pass a new one."""
        pixels = self._pixels
        if pixels is None:
            raise DisplayUnavailable("the framebuffer display is closed")
        if frame is self._last:
            self.repeats += 1
            return
        self._last = frame
        source, region = self._target(frame, pixels)
        written = cv2.cvtColor(source, self._code, dst=region)
        if written is not region:  # OpenCV allocated instead of writing in place: never with these layouts
            region[:] = written
        self.frames += 1

    def close(self) -> None:
        self._last = None
        if self._pixels is not None:
            self._pixels = None
            self._map.close()
            os.close(self._fd)


class WindowDisplay:
    """A desktop window for development (OpenCV highgui), scaled down to fit a laptop screen."""

    name = "window"

    def __init__(self, title: str = "feelium projector", max_width: int = 960) -> None:
        self.title = title
        self.max_width = max_width
        try:
            cv2.namedWindow(title, cv2.WINDOW_AUTOSIZE)
        except cv2.error as exc:
            raise DisplayUnavailable(
                "this OpenCV has no GUI (opencv-python-headless); use the sim backend and watch "
                "/video/projector.mjpeg, or install a GUI build of OpenCV for a window"
            ) from exc
        self.frames = 0

    def show(self, frame: np.ndarray) -> None:
        h, w = frame.shape[:2]
        if w > self.max_width:
            frame = cv2.resize(frame, (self.max_width, int(h * self.max_width / w)), interpolation=cv2.INTER_AREA)
        cv2.imshow(self.title, frame)
        cv2.waitKey(1)  # lets highgui paint; the daemon never reads keys
        self.frames += 1

    def close(self) -> None:
        try:
            cv2.destroyWindow(self.title)
        except cv2.error:
            pass


def open_display(backend: str, device: str) -> Display:
    """The configured backend; ``auto`` is the framebuffer when ``device`` exists, else sim."""
    if backend == "sim" or (backend == "auto" and not Path(device).exists()):
        return SimDisplay()
    if backend == "window":
        return WindowDisplay()
    return FbdevDisplay(device)
