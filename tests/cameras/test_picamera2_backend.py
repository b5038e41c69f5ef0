"""The picamera2 backends against a stand-in module (picamera2 only exists on the blimp)."""

from __future__ import annotations

import sys
import threading
import time
import types

import numpy as np
import pytest

from feelium.cameras import picamera2_backend
from feelium.cameras.base import CameraUnavailable, Jpeg
from feelium.cameras.config import FrontCameraConfig
from feelium.cameras.picamera2_backend import (
    Picamera2FrontCamera,
    Picamera2RearCamera,
    camera_count,
    hardware_jpeg_available,
    load_picamera2,
)
from feelium.cameras.select import front_jpeg_encoder

W, H = 64, 48
STRIDE = 80  # libcamera pads rows; the luma must be cut out of the padded plane
PERIOD_NS = 66_666_667


class FakeRequest:
    def __init__(self, camera, n):
        self.camera, self.n = camera, n
        self.stream_map = {"main": ("stream", "main"), "lores": ("stream", "lores")}  # libcamera's stream objects
        self.released = False

    def get_metadata(self):
        return {
            "SensorTimestamp": 5_000_000_000 + self.n * PERIOD_NS,
            "ExposureTime": 10000 + self.n,
            "AnalogueGain": 2.0,
            "ColourGains": (1.5, 1.8),
        }

    def make_array(self, stream):
        if stream == "lores":
            plane = np.full((H * 3 // 2, STRIDE), 7, np.uint8)
            plane[:H, :W] = self.n % 256
            return plane
        return np.full((H, W, 4), self.n % 256, np.uint8)

    def release(self):
        self.released = True
        self.camera.released += 1


class FakePicamera2:
    cameras = [{"Model": "imx500", "Num": 0}, {"Model": "imx708_wide", "Num": 1}]

    def __init__(self, camera_num=0):
        self.camera_num = camera_num
        self.controls_set = []
        self.n = 0
        self.released = 0
        self.held = 0  # requests an encoder still holds
        self.started = self.closed = False

    @classmethod
    def global_camera_info(cls):
        return cls.cameras

    def create_video_configuration(self, **kwargs):
        self.configuration = kwargs
        return kwargs

    def configure(self, config):
        self.configured = config

    def start(self):
        self.started = True

    def stop(self):
        self.started = False

    def close(self):
        self.closed = True

    def set_controls(self, controls):
        self.controls_set.append(controls)

    def stream_configuration(self, name):
        return {"stride": 96, **self.configured[name]}

    def capture_request(self):
        request = FakeRequest(self, self.n)
        self.n += 1
        return request


class FakeOutput:
    """picamera2.outputs.Output: the encoders take nothing else."""


class FakeMJPEGEncoder:
    """The VideoCore's MJPEG encoder as picamera2 drives it by hand: ``encode`` takes a reference on the request
    and the JPEG comes later, from another thread, in the order the frames were queued."""

    available = True
    emit = True  # False: a stuck encoder that never returns a JPEG

    def __init__(self, bitrate=None):
        if not self.available:
            raise RuntimeError("Hardware MJPEG not available on this platform")
        self.bitrate = bitrate
        self.running = False
        self.queued = []

    @property
    def output(self):
        return self._output

    @output.setter
    def output(self, value):
        if not isinstance(value, FakeOutput):
            raise RuntimeError("Must pass Output")
        self._output = value

    def start(self):
        self.running = True

    def stop(self):
        self.running = False

    def encode(self, stream, request):
        assert self.running and stream == ("stream", "main")  # the object: some versions do not look a name up
        request.camera.held += 1  # the encoder's own reference, dropped once the JPEG is out
        self.queued.append(request.n)
        if self.emit:
            def finish(n=request.n):
                self._output.outputframe(b"\xff\xd8jpeg-%d" % n, True, 1000 * n, None, False)
                request.camera.held -= 1

            threading.Timer(0.005, finish).start()


@pytest.fixture
def module():
    FakeMJPEGEncoder.available, FakeMJPEGEncoder.emit = True, True
    return types.SimpleNamespace(
        Picamera2=FakePicamera2,
        encoders=types.SimpleNamespace(MJPEGEncoder=FakeMJPEGEncoder),
        outputs=types.SimpleNamespace(Output=FakeOutput),
    )


def test_rear_camera_locks_exposure_after_settling_and_delivers_luma_on_the_sensor_clock(module):
    camera = Picamera2RearCamera(
        index=0, width=W, height=H, fps=15.0, settle_s=1.0, roi=(4, 4, 40, 30), module=module, boottime_ahead=lambda: 2.0
    )
    cam = camera._camera
    assert cam.configuration["lores"] == {"size": (W, H), "format": "YUV420"}
    frame = camera.read()
    # frames 0..15 settle (t < 1 s), frame 15 locks at t = 1.0, frames until 1.3 s are skipped
    assert len(cam.controls_set) == 1
    lock = cam.controls_set[0]
    assert lock["AeEnable"] is False and lock["AwbEnable"] is False
    assert lock["ExposureTime"] == 10015 and lock["AnalogueGain"] == 2.0 and lock["ColourGains"] == (1.5, 1.8)
    # on the daemon's clock: the sensor's CLOCK_BOOTTIME (5 s + n periods) less the 2 s it runs ahead
    assert frame.t == pytest.approx(5.0 - 2.0 + (cam.n - 1) * PERIOD_NS / 1e9) and frame.t >= 3.0 + 1.3
    assert frame.image.shape == (H, W) and frame.image.flags["C_CONTIGUOUS"]
    assert np.all(frame.image == (cam.n - 1) % 256)  # the luma plane, not the padding or chroma
    assert frame.roi == (4, 4, 40, 30)
    second = camera.read()
    assert second.t - frame.t == pytest.approx(PERIOD_NS / 1e9)
    assert cam.released == cam.n  # every request goes back to libcamera
    camera.close()
    camera.close()
    assert cam.closed and camera.read() is None


def test_front_camera_delivers_bgr(module):
    camera = Picamera2FrontCamera(index=1, width=W, height=H, fps=15.0, module=module, boottime_ahead=lambda: 0.5)
    assert camera._camera.camera_num == 1
    frame = camera.read()
    assert frame.image.shape == (H, W, 3) and frame.t == pytest.approx(4.5)
    assert camera.read().t == pytest.approx(4.5 + PERIOD_NS / 1e9)


def test_front_camera_hands_over_the_hardware_encoders_jpegs_each_with_its_own_sensor_time(module):
    camera = Picamera2FrontCamera(index=1, width=W, height=H, fps=15.0, jpeg="hardware", module=module, boottime_ahead=lambda: 0.5)
    cam, encoder = camera._camera, camera._encoder
    assert cam.configured["main"]["format"] == "YUV420"  # what the encoder takes, not RGB for OpenCV
    assert encoder.running and (encoder.size, encoder.format, encoder.stride) == ((W, H), "YUV420", 96)
    assert encoder.bitrate == round(picamera2_backend.HARDWARE_JPEG_BITS_PER_PIXEL * W * H * 15.0)
    frames = [camera.read() for _ in range(3)]
    assert [f.image.data for f in frames] == [b"\xff\xd8jpeg-0", b"\xff\xd8jpeg-1", b"\xff\xd8jpeg-2"]
    assert all(isinstance(f.image, Jpeg) and (f.image.width, f.image.height) == (W, H) for f in frames)
    assert [f.t for f in frames] == pytest.approx([4.5 + n * PERIOD_NS / 1e9 for n in range(3)])
    assert cam.released == 3  # our reference goes back at once; the encoder drops its own when the JPEG is out
    camera.close()
    assert not encoder.running and cam.closed and camera.read() is None


def test_a_stuck_hardware_encoder_is_an_error_the_service_restarts_on(module, monkeypatch):
    monkeypatch.setattr(picamera2_backend, "ENCODE_TIMEOUT_S", 0.05)
    camera = Picamera2FrontCamera(index=1, width=W, height=H, fps=15.0, jpeg="hardware", module=module)
    FakeMJPEGEncoder.emit = False
    with pytest.raises(OSError, match="hardware JPEG encoder returned nothing"):
        camera.read()
    camera.close()


def test_no_hardware_encoder_says_so_and_auto_falls_back_to_software(module):
    assert hardware_jpeg_available(module)
    FakeMJPEGEncoder.available = False
    assert not hardware_jpeg_available(module)
    with pytest.raises(CameraUnavailable, match="no hardware JPEG encoder.*jpeg = \"software\""):
        Picamera2FrontCamera(index=1, width=W, height=H, fps=15.0, jpeg="hardware", module=module)
    assert front_jpeg_encoder(FrontCameraConfig(jpeg="auto"), module) == "software"
    assert front_jpeg_encoder(FrontCameraConfig(jpeg="hardware"), module) == "hardware"  # asked for: fails loudly at open
    FakeMJPEGEncoder.available = True
    assert front_jpeg_encoder(FrontCameraConfig(jpeg="auto"), module) == "hardware"
    assert front_jpeg_encoder(FrontCameraConfig(jpeg="software"), module) == "software"


def test_a_missing_camera_says_what_to_check(module):
    with pytest.raises(CameraUnavailable, match="no camera 5 .*'video' group"):
        Picamera2RearCamera(index=5, width=W, height=H, fps=15.0, settle_s=0.0, roi=None, module=module)


def test_a_missing_library_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "picamera2", None)  # makes the import fail
    with pytest.raises(CameraUnavailable, match="apt install python3-picamera2"):
        load_picamera2()
    assert camera_count() == 0 or picamera2_backend.importlib.util.find_spec("picamera2") is not None


@pytest.mark.parametrize(
    ("raises", "says"),
    [
        ('ImportError("numpy.core.multiarray failed to import")', "cannot load with numpy .*constraints/pi-bookworm.txt"),
        ('ValueError("numpy.dtype size changed, may indicate binary incompatibility")', "cannot load with numpy"),
        ('RuntimeError("libcamera: no IPA module")', "installed but failed to load: RuntimeError: libcamera"),
    ],
)
def test_an_installed_library_that_fails_to_load_says_why_not_install_it(tmp_path, monkeypatch, raises, says):
    package = tmp_path / "picamera2"
    package.mkdir()
    (package / "__init__.py").write_text(f"raise {raises}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "picamera2", raising=False)
    with pytest.raises(CameraUnavailable, match=says) as caught:
        load_picamera2()
    assert "apt install" not in str(caught.value)


def test_camera_count_of_a_module(module):
    assert camera_count(module) == 2


def test_the_sensor_clock_maps_onto_the_daemon_clock() -> None:
    """libcamera stamps with CLOCK_BOOTTIME; a frame exposed now must read as about now on time.monotonic."""
    now_ns = time.clock_gettime_ns(time.CLOCK_BOOTTIME)
    assert picamera2_backend.sensor_time_s(now_ns, picamera2_backend.boottime_ahead_s()) == pytest.approx(time.monotonic(), abs=0.01)
