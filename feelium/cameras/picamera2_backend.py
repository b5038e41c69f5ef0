"""The Raspberry Pi cameras through picamera2 (libcamera): the rear IMX500 and the front fisheye.

picamera2 exists only on the blimp (Raspberry Pi OS), so it is imported here,
lazily, and nowhere else; tests pass a stand-in module. The rear camera's
exposure, gain and white balance run automatically for a settling period and
are then locked, because the touch pipeline's adaptive reference assumes a
fixed exposure: an auto-exposure step would look like a shadow.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import time
from collections.abc import Callable
from types import ModuleType
from typing import Any

import numpy as np

from feelium.cameras.base import CameraUnavailable, ClosableReader, Frame, Roi

log = logging.getLogger(__name__)

INSTALL_HINT = (
    "picamera2 is not installed: on Raspberry Pi OS run `sudo apt install python3-picamera2` "
    "(pip-only setups: `pip install 'feelium[pi]'` with libcamera present); the user needs the 'video' group"
)


def boottime_ahead_s() -> float:
    """How far libcamera's clock (``SensorTimestamp``: CLOCK_BOOTTIME) is ahead of the daemon's (CLOCK_MONOTONIC).

    The two differ by the time the board spent suspended; subtracting this puts frame times on the daemon's
    clock, the one every timestamp of the headset API is on (``hub.clock``, ``time.monotonic``).
    """
    return time.clock_gettime(time.CLOCK_BOOTTIME) - time.monotonic()


def sensor_time_s(stamp_ns: int, boottime_ahead: float) -> float:
    """A ``SensorTimestamp`` on the daemon's monotonic clock, in seconds."""
    return stamp_ns / 1e9 - boottime_ahead


AFTER_LOCK_S = 0.3  # frames still exposed with the old automatic values right after locking are skipped


NUMPY_ABI_WORDS = ("numpy", "dtype size changed", "_ARRAY_API", "multiarray")


def load_picamera2() -> ModuleType:
    """Import picamera2 or raise :class:`CameraUnavailable` saying what to do.

    Installed but failing to load is not the same trouble as absent: Debian's picamera2 and simplejpeg are
    built against numpy 1.24, and a numpy 2 in the venv makes their import fail ("numpy.core.multiarray failed
    to import", "dtype size changed"). Telling the user to install what is there would send them round in a
    circle, so that case names numpy and the constraints file instead.
    """
    try:
        return importlib.import_module("picamera2")
    except Exception as exc:
        installed = importlib.util.find_spec("picamera2") is not None
        if installed and any(word in str(exc) for word in NUMPY_ABI_WORDS):
            import numpy

            raise CameraUnavailable(
                f"picamera2 is installed but cannot load with numpy {numpy.__version__} ({exc}): Debian's camera "
                "stack needs numpy < 2; reinstall the venv with `-c constraints/pi-bookworm.txt` (docs/deploy.md)"
            ) from exc
        if installed:
            raise CameraUnavailable(f"picamera2 is installed but failed to load: {type(exc).__name__}: {exc}") from exc
        raise CameraUnavailable(INSTALL_HINT) from exc


def camera_count(module: ModuleType | None = None) -> int:
    """How many cameras libcamera sees; 0 without picamera2 (cheap on a laptop: nothing is imported)."""
    if module is None:
        if importlib.util.find_spec("picamera2") is None:
            return 0
        try:
            module = importlib.import_module("picamera2")
        except Exception:  # a broken libcamera install counts as no camera
            return 0
    try:
        return len(module.Picamera2.global_camera_info())
    except Exception:
        return 0


def _open(module: ModuleType, index: int) -> Any:
    found = camera_count(module)
    if index >= found:
        raise CameraUnavailable(
            f"no camera {index} found by libcamera (it sees {found}): check the ribbon cable, "
            "`rpicam-hello --list-cameras`, and that the user is in the 'video' group"
        )
    try:
        return module.Picamera2(camera_num=index)
    except PermissionError as exc:
        raise CameraUnavailable(f"camera {index}: permission denied; add the user to the 'video' group") from exc
    except RuntimeError as exc:
        raise CameraUnavailable(f"camera {index} cannot be opened ({exc}); is another process using it?") from exc


class Picamera2RearCamera:
    """Gray frames from the luma plane of a low-resolution YUV stream, stamped with SensorTimestamp on the daemon clock."""

    name = "picamera2"
    realtime = True

    def __init__(
        self,
        *,
        index: int,
        width: int,
        height: int,
        fps: float,
        settle_s: float,
        roi: Roi | None,
        module: ModuleType | None = None,
        boottime_ahead: Callable[[], float] = boottime_ahead_s,
    ) -> None:
        module = module if module is not None else load_picamera2()
        self._boottime_ahead = boottime_ahead()
        self.size = (width, height)
        self.roi = roi
        self._settle_s = settle_s
        self._camera = _open(module, index)
        main = (min(2 * width, 2028), min(2 * height, 1520))
        config = self._camera.create_video_configuration(
            main={"size": main, "format": "YUV420"},
            lores={"size": (width, height), "format": "YUV420"},
            controls={"FrameRate": float(fps), "AeEnable": True, "AwbEnable": True},
            buffer_count=4,
        )
        self._camera.configure(config)
        self._camera.start()
        self._first_ns: int | None = None
        self._locked_at: float | None = None
        self._guard = ClosableReader()

    def _lock_exposure(self, metadata: dict[str, Any], t: float) -> None:
        controls: dict[str, Any] = {"AeEnable": False, "AwbEnable": False}
        for key in ("ExposureTime", "AnalogueGain", "ColourGains"):
            if key in metadata:
                controls[key] = metadata[key]
        self._camera.set_controls(controls)
        self._locked_at = t
        log.info("rear camera exposure locked after %.1f s: %s", t, controls)

    def read(self) -> Frame | None:
        with self._guard:
            if self._guard.closed:
                return None
            while True:
                metadata, yuv = _capture(self._camera, "lores")
                stamp = int(metadata["SensorTimestamp"])
                if self._first_ns is None:
                    self._first_ns = stamp
                running = (stamp - self._first_ns) / 1e9
                if self._locked_at is None:
                    if running >= self._settle_s:
                        self._lock_exposure(metadata, running)
                    continue
                if running < self._locked_at + AFTER_LOCK_S:
                    continue
                t = sensor_time_s(stamp, self._boottime_ahead)
                width, height = self.size
                luma = np.ascontiguousarray(yuv[:height, :width])  # Y plane of I420; rows may be padded to a stride
                return Frame(t=t, image=luma, roi=self.roi)

    def close(self) -> None:
        def release() -> None:
            try:
                self._camera.stop()
            finally:
                self._camera.close()

        self._guard.close(release)


def _capture(camera: Any, stream: str) -> tuple[dict[str, Any], np.ndarray]:
    """One request's metadata and the named stream's pixels; the buffer goes back to the camera at once."""
    request = camera.capture_request()
    try:
        return request.get_metadata(), request.make_array(stream)
    finally:
        request.release()


class Picamera2FrontCamera:
    """BGR frames of the fisheye camera (picamera2's "RGB888" is BGR in memory, as OpenCV wants)."""

    name = "picamera2"
    realtime = True

    def __init__(
        self, *, index: int, width: int, height: int, fps: float, module: ModuleType | None = None,
        boottime_ahead: Callable[[], float] = boottime_ahead_s,
    ) -> None:
        module = module if module is not None else load_picamera2()
        self._boottime_ahead = boottime_ahead()
        self._camera = _open(module, index)
        config = self._camera.create_video_configuration(
            main={"size": (width, height), "format": "RGB888"}, controls={"FrameRate": float(fps)}, buffer_count=3
        )
        self._camera.configure(config)
        self._camera.start()
        self._guard = ClosableReader()

    def read(self) -> Frame | None:
        with self._guard:
            if self._guard.closed:
                return None
            metadata, image = _capture(self._camera, "main")
            stamp = int(metadata["SensorTimestamp"])
            return Frame(t=sensor_time_s(stamp, self._boottime_ahead), image=np.ascontiguousarray(image[:, :, :3]))

    def close(self) -> None:
        def release() -> None:
            try:
                self._camera.stop()
            finally:
                self._camera.close()

        self._guard.close(release)
