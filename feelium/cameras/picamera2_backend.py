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
import queue
import time
from collections.abc import Callable
from types import ModuleType
from typing import Any

import numpy as np

from feelium.cameras.base import CameraUnavailable, ClosableReader, Frame, Jpeg, Roi

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


# The hardware encoder's bits per pixel and frame, set explicitly (picamera2 would otherwise pick a bit rate from its
# quality table, which changed between versions): its current MEDIUM, 30 Mb/s at 1080p30, about 18 KB a 640x480
# frame, near the 20 KB the software path's frames of the simulated room take at [http] jpeg_quality 80.
HARDWARE_JPEG_BITS_PER_PIXEL = 30e6 / (1920 * 1080 * 30)
ENCODE_TIMEOUT_S = 1.0  # a frame not encoded in this long: the encoder is stuck, and the camera is reopened


def _submodule(module: ModuleType, name: str) -> Any:
    """picamera2's ``encoders`` or ``outputs``: the attribute once the package loaded it, else imported."""
    found = getattr(module, name, None)
    return found if found is not None else importlib.import_module(f"{module.__name__}.{name}")


def hardware_jpeg_available(module: ModuleType) -> bool:
    """Whether picamera2 offers the VideoCore's MJPEG encoder here (the Pi Zero 2 W to the Pi 4 do; the Pi 5 has none)."""
    try:
        _submodule(module, "encoders").MJPEGEncoder()
    except Exception:
        return False
    return True


class _EncodedFrames:
    """The hardware encoder's JPEGs in the order the frames were queued: the V4L2 memory-to-memory encoder keeps
    the order, so the n-th JPEG is the n-th frame handed to it."""

    def __init__(self) -> None:
        self._ready: queue.Queue[bytes] = queue.Queue()

    def put(self, frame: Any) -> None:
        self._ready.put(bytes(frame))

    def next(self, timeout: float) -> bytes | None:
        try:
            return self._ready.get(timeout=timeout)
        except queue.Empty:
            return None


def _as_picamera2_output(module: ModuleType, frames: _EncodedFrames) -> Any:
    """An instance of picamera2's ``Output`` (its encoders refuse anything else) that hands each JPEG to ``frames``;
    picamera2 calls it from its encoder thread."""
    outputs = _submodule(module, "outputs")

    class EncodedFramesOutput(outputs.Output):  # type: ignore[misc, name-defined]
        def outputframe(self, frame: Any, *_args: Any, **_kwargs: Any) -> None:  # later versions pass more arguments
            frames.put(frame)

    return EncodedFramesOutput()


class Picamera2FrontCamera:
    """The fisheye camera's frames: JPEGs from the VideoCore's encoder (``jpeg="hardware"``), else BGR frames
    (picamera2's "RGB888" is BGR in memory, as OpenCV wants) for the daemon to encode in software.

    Why the hardware path: the front frames only go to the headset, as JPEG; on a Pi Zero 2 W encoding 640x480 at
    15 fps in software takes the ARM cores ~0.07 of a core (docs/performance.md), the VideoCore's encoder almost
    none. Each frame is handed to the encoder by hand and its JPEG awaited, so it keeps its own SensorTimestamp.
    """

    name = "picamera2"
    realtime = True

    def __init__(
        self, *, index: int, width: int, height: int, fps: float, jpeg: str = "software",
        module: ModuleType | None = None, boottime_ahead: Callable[[], float] = boottime_ahead_s,
    ) -> None:  # fmt: skip
        if jpeg not in ("hardware", "software"):
            raise ValueError(f"jpeg must be 'hardware' or 'software', got {jpeg!r}")
        module = module if module is not None else load_picamera2()
        self._boottime_ahead = boottime_ahead()
        self.size = (width, height)
        self.jpeg = jpeg
        self._camera = _open(module, index)
        pixels = "YUV420" if jpeg == "hardware" else "RGB888"  # what the encoder takes; what OpenCV takes
        config = self._camera.create_video_configuration(
            main={"size": (width, height), "format": pixels}, controls={"FrameRate": float(fps)}, buffer_count=3
        )
        self._camera.configure(config)
        self._encoded: _EncodedFrames | None = None
        self._encoder: Any = None
        if jpeg == "hardware":
            self._start_encoder(module, width, height, fps)
        self._camera.start()
        self._guard = ClosableReader()

    def _start_encoder(self, module: ModuleType, width: int, height: int, fps: float) -> None:
        try:
            encoder = _submodule(module, "encoders").MJPEGEncoder(bitrate=int(HARDWARE_JPEG_BITS_PER_PIXEL * width * height * fps))
        except RuntimeError as exc:  # "Hardware MJPEG not available on this platform" (a Pi 5)
            self._camera.close()
            raise CameraUnavailable(f"front camera: no hardware JPEG encoder ({exc}); set front_camera.jpeg = \"software\"") from exc
        encoder.size = (width, height)
        encoder.format = "YUV420"
        encoder.stride = int(self._camera.stream_configuration("main")["stride"])
        self._encoded = _EncodedFrames()
        encoder.output = _as_picamera2_output(module, self._encoded)
        encoder.start()
        self._encoder = encoder

    def read(self) -> Frame | None:
        with self._guard:
            if self._guard.closed:
                return None
            if self._encoder is None:
                metadata, image = _capture(self._camera, "main")
                stamp = int(metadata["SensorTimestamp"])
                return Frame(t=sensor_time_s(stamp, self._boottime_ahead), image=np.ascontiguousarray(image[:, :, :3]))
            request = self._camera.capture_request()
            try:
                metadata = request.get_metadata()
                # The stream object, not its name: some picamera2 versions' V4L2 encoder reads ``stream.configuration``
                # without looking the name up. The encoder holds the buffer until its JPEG is out.
                self._encoder.encode(getattr(request, "stream_map", {}).get("main", "main"), request)
            finally:
                request.release()
            assert self._encoded is not None
            data = self._encoded.next(ENCODE_TIMEOUT_S)
            if data is None:
                raise OSError(f"the hardware JPEG encoder returned nothing in {ENCODE_TIMEOUT_S:.0f} s")
            stamp = int(metadata["SensorTimestamp"])
            return Frame(t=sensor_time_s(stamp, self._boottime_ahead), image=Jpeg(data, *self.size))

    def close(self) -> None:
        def release() -> None:
            try:
                if self._encoder is not None:
                    self._encoder.stop()
            finally:
                try:
                    self._camera.stop()
                finally:
                    self._camera.close()

        self._guard.close(release)
