"""The USB (V4L2) front camera against a stand-in for OpenCV's capture: its own MJPEG forwarded, else BGR frames."""

from __future__ import annotations

import logging

import cv2
import numpy as np
import pytest

from feelium.cameras import select
from feelium.cameras.base import CameraUnavailable, Jpeg
from feelium.cameras.mjpeg import STANDARD_DHT
from feelium.cameras.select import CameraSource
from feelium.cameras.v4l2 import MJPG, V4l2Camera
from feelium.daemon.config import Config
from feelium.front_camera.service import FrontCameraService
from feelium.hub import Hub

W, H = 64, 48
YUYV = cv2.VideoWriter_fourcc(*"YUYV")


def _uvc_jpeg(value: int) -> bytes:
    """A frame as UVC cameras send it: a JPEG without its Huffman tables (the "AVI1" convention)."""
    image = np.zeros((H, W, 3), np.uint8)
    image[:, : W // 2] = (value, 255 - value, 40)
    data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])[1].tobytes()
    while (start := data.find(b"\xff\xc4")) >= 0:
        data = data[:start] + data[start + 2 + (data[start + 2] << 8 | data[start + 3]) :]
    return data


class FakeCapture:
    """OpenCV's V4L2 capture as far as the camera uses it: a FOURCC the driver does not offer is refused and the
    old one kept; the driver picks the nearest size it has for a format; with CAP_PROP_CONVERT_RGB off an MJPEG
    frame comes as one row of its bytes, with it on as the decoded BGR image."""

    def __init__(self, formats: dict[int, tuple[int, int]], frames: list[bytes], honour_convert: bool = True) -> None:
        self.formats = formats  # fourcc -> the one size the camera gives in it
        self.frames = list(frames)
        self.honour_convert = honour_convert
        self.fourcc = next(iter(formats))
        self.convert = 1
        self.calls: list[tuple[int, float]] = []
        self.released = False

    def isOpened(self) -> bool:  # noqa: N802 (OpenCV's name)
        return True

    def set(self, prop: int, value: float) -> bool:
        self.calls.append((prop, value))
        if prop == cv2.CAP_PROP_FOURCC:
            if int(value) not in self.formats:
                return False
            self.fourcc = int(value)
        elif prop == cv2.CAP_PROP_CONVERT_RGB:
            self.convert = int(value) if self.honour_convert else 1
        return True

    def get(self, prop: int) -> float:
        size = self.formats[self.fourcc]
        return float({cv2.CAP_PROP_FOURCC: self.fourcc, cv2.CAP_PROP_CONVERT_RGB: self.convert,
                      cv2.CAP_PROP_FRAME_WIDTH: size[0], cv2.CAP_PROP_FRAME_HEIGHT: size[1]}.get(prop, 0))  # fmt: skip

    def read(self) -> tuple[bool, np.ndarray | None]:
        if not self.frames:
            return False, None
        data = self.frames.pop(0)
        if self.fourcc == MJPG and not self.convert:
            return True, np.frombuffer(data, np.uint8).reshape(1, -1).copy()
        width, height = self.formats[self.fourcc]
        return True, np.full((height, width, 3), len(self.frames), np.uint8)

    def release(self) -> None:
        self.released = True


@pytest.fixture
def device(tmp_path):
    path = tmp_path / "video0"
    path.touch()
    return str(path)


def _camera(device: str, capture: FakeCapture, jpeg: str) -> V4l2Camera:
    return V4l2Camera(device, W, H, 15.0, jpeg=jpeg, clock=iter(range(1, 100)).__next__, capture=lambda _d: capture)


@pytest.mark.parametrize("jpeg", ["auto", "hardware"])
def test_the_cameras_mjpeg_is_handed_over_undecoded(device, jpeg):
    frames = [_uvc_jpeg(10), _uvc_jpeg(200)]
    capture = FakeCapture({YUYV: (W, H), MJPG: (W, H)}, frames)
    camera = _camera(device, capture, jpeg)
    assert camera.jpeg == "hardware" and capture.convert == 0
    first = camera.read()
    assert isinstance(first.image, Jpeg) and first.image.data == frames[0]
    assert (first.image.width, first.image.height) == (W, H)
    assert first.t == 1


async def test_mjpeg_frames_reach_the_headset_with_tables_and_a_broken_one_is_counted(device, caplog):
    frames = [_uvc_jpeg(10), b"\xff\xd8\xff\xe0 cut", _uvc_jpeg(200)[:-300], _uvc_jpeg(200)]
    capture = FakeCapture({YUYV: (W, H), MJPG: (W, H)}, frames)
    hub = Hub()
    service = FrontCameraService(CameraSource("v4l2", lambda: _camera(device, capture, "auto")), hub)
    with pytest.raises(OSError, match="stopped delivering"):  # the stand-in's frames run out
        await service.run()
    health = service.health()
    assert health["frames"] == 2 and health["bad_frames"] == 2 and health["jpeg_by"] == "camera"
    sent = hub.front_video.get().value
    assert isinstance(sent, Jpeg) and STANDARD_DHT in sent.data
    decoded = cv2.imdecode(np.frombuffer(sent.data, np.uint8), cv2.IMREAD_COLOR)
    assert decoded.shape == (H, W, 3)
    assert np.abs(decoded[H // 2, 5].astype(int) - (200, 55, 40)).max() < 8  # the last frame, made of value 200
    skipped = [r for r in caplog.records if "skipped" in r.getMessage()]
    assert len(skipped) == 1 and "bad_frames" in skipped[0].getMessage()  # the first bad frame of a run only
    assert capture.released


@pytest.mark.parametrize(
    ("formats", "honour_convert", "why"),
    [
        ({YUYV: (W, H)}, True, "offers no MJPEG (it delivers YUYV)"),
        ({YUYV: (W, H), MJPG: (2 * W, 2 * H)}, True, f"MJPEG comes at {2 * W}x{2 * H}, not the configured {W}x{H}"),
        ({YUYV: (W, H), MJPG: (W, H)}, False, "CAP_PROP_CONVERT_RGB"),
    ],
)
def test_auto_falls_back_to_software_with_one_log_line_and_the_capture_as_it_was(
    device, caplog, formats, honour_convert, why
):
    capture = FakeCapture(formats, [b"", b""], honour_convert)
    with caplog.at_level(logging.INFO, logger="feelium.cameras.v4l2"):
        camera = _camera(device, capture, "auto")
    assert camera.jpeg == "software"
    said = [r.getMessage() for r in caplog.records if r.name == "feelium.cameras.v4l2"]
    assert len(said) == 1 and why in said[0] and said[0].endswith("the daemon encodes its JPEGs in software")
    assert capture.fourcc == YUYV and capture.convert == 1
    frame = camera.read()
    assert isinstance(frame.image, np.ndarray) and frame.image.shape == (H, W, 3)  # BGR, resized if it must be


async def test_without_mjpeg_the_service_says_the_daemon_encodes(device):
    capture = FakeCapture({YUYV: (W, H)}, [b"", b""])
    service = FrontCameraService(CameraSource("v4l2", lambda: _camera(device, capture, "auto")), Hub())
    with pytest.raises(OSError):
        await service.run()
    assert service.health()["frames"] == 2 and service.health()["jpeg_by"] == "daemon"


def test_hardware_without_mjpeg_fails_the_open_saying_what_to_set(device):
    capture = FakeCapture({YUYV: (W, H)}, [])
    with pytest.raises(CameraUnavailable, match='offers no MJPEG.*set front_camera.jpeg = "software"'):
        _camera(device, capture, "hardware")
    assert capture.released


def test_software_never_asks_for_mjpeg(device):
    capture = FakeCapture({YUYV: (W, H), MJPG: (W, H)}, [b""])
    camera = _camera(device, capture, "software")
    assert camera.jpeg == "software"
    assert not any(prop in (cv2.CAP_PROP_FOURCC, cv2.CAP_PROP_CONVERT_RGB) for prop, _ in capture.calls)
    assert isinstance(camera.read().image, np.ndarray)


def test_the_front_source_passes_the_jpeg_setting_to_a_usb_camera(monkeypatch):
    opened = {}

    def fake(device, width, height, fps, jpeg):
        opened.update(device=device, jpeg=jpeg)
        return "camera"

    monkeypatch.setattr("feelium.cameras.v4l2.V4l2Camera", fake)
    config = Config()
    cfg = type(config.front_camera)(backend="v4l2", device="/dev/video4", jpeg="hardware")
    source = select.front_camera_source(cfg, sim_seed=1)
    assert source.backend == "v4l2" and source.open() == "camera"
    assert opened == {"device": "/dev/video4", "jpeg": "hardware"}
