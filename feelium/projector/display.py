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

import os
from pathlib import Path
from typing import Protocol, runtime_checkable

import cv2
import numpy as np


class DisplayUnavailable(RuntimeError):
    """A display backend cannot start (device missing, unsupported format): one line saying what to do."""


@runtime_checkable
class Display(Protocol):
    name: str

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


def to_bgr565(frame: np.ndarray) -> np.ndarray:
    """BGR uint8 (H, W, 3) to little-endian RGB565 words (H, W) uint16, as a 16-bit framebuffer stores them."""
    b = frame[:, :, 0].astype(np.uint16)
    g = frame[:, :, 1].astype(np.uint16)
    r = frame[:, :, 2].astype(np.uint16)
    return ((r >> 3) << 11) | ((g >> 2) << 5) | (b >> 3)


def to_xrgb8888(frame: np.ndarray) -> np.ndarray:
    """BGR uint8 (H, W, 3) to (H, W, 4) bytes B, G, R, X: little-endian XRGB8888."""
    return cv2.cvtColor(frame, cv2.COLOR_BGR2BGRA)


def _read_sysfs(path: Path) -> str:
    try:
        return path.read_text().strip()
    except OSError as exc:
        raise DisplayUnavailable(f"cannot read {path}: {exc.strerror}; is this a Linux framebuffer device?") from exc


class FbdevDisplay:
    """Writes frames into a Linux framebuffer, letterboxed (scaled to fit, centred) into its virtual size."""

    name = "fbdev"

    def __init__(self, device: str = "/dev/fb0", sysfs_root: str = "/sys/class/graphics") -> None:
        dev = Path(device)
        sysfs = Path(sysfs_root) / dev.name
        w, h = (int(v) for v in _read_sysfs(sysfs / "virtual_size").split(","))
        self.bpp = int(_read_sysfs(sysfs / "bits_per_pixel"))
        if self.bpp not in (16, 32):
            raise DisplayUnavailable(f"{device}: {self.bpp} bits per pixel is not supported (16 or 32)")
        stride_file = sysfs / "stride"
        self.stride = int(_read_sysfs(stride_file)) if stride_file.exists() else w * self.bpp // 8
        self.size = (w, h)
        try:
            self._fd = os.open(device, os.O_WRONLY)
        except OSError as exc:
            raise DisplayUnavailable(f"cannot open {device}: {exc.strerror} (is the user in the 'video' group?)") from exc
        self.frames = 0
        self.repeats = 0  # frames not written again: the framebuffer already held them
        self._last: np.ndarray | None = None

    def _fit(self, frame: np.ndarray) -> np.ndarray:
        w, h = self.size
        fh, fw = frame.shape[:2]
        if (fw, fh) == (w, h):
            return frame
        scale = min(w / fw, h / fh)
        nw, nh = max(1, int(fw * scale)), max(1, int(fh * scale))
        out = np.zeros((h, w, 3), np.uint8)
        x0, y0 = (w - nw) // 2, (h - nh) // 2
        out[y0 : y0 + nh, x0 : x0 + nw] = cv2.resize(frame, (nw, nh), interpolation=cv2.INTER_AREA)
        return out

    def show(self, frame: np.ndarray) -> None:
        """Convert and write ``frame``, unless it is the very array written last: the framebuffer still holds
        it, and the projector service hands the same array again for every frame in which nothing changed (its
        frames are never written while held), which spares a 1280x720 conversion and a 1.8-3.7 MB write per
        such frame. A caller that changes an array in place must pass a new one."""
        if frame is self._last:
            self.repeats += 1
            return
        self._last = frame
        fitted = self._fit(frame)
        pixels = to_bgr565(fitted) if self.bpp == 16 else to_xrgb8888(fitted)
        row_bytes = pixels.shape[1] * self.bpp // 8
        raw = pixels.reshape(pixels.shape[0], -1).view(np.uint8)
        if self.stride != row_bytes:
            padded = np.zeros((raw.shape[0], self.stride), np.uint8)
            padded[:, :row_bytes] = raw
            raw = padded
        os.pwrite(self._fd, np.ascontiguousarray(raw).tobytes(), 0)
        self.frames += 1

    def close(self) -> None:
        self._last = None
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


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
