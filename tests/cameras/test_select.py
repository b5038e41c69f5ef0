"""Backend choice: auto falls back to the simulator without hardware; off means no service."""

from __future__ import annotations

import dataclasses
import os

import pytest

from feelium.cameras import select
from feelium.daemon.assembly import build_front_camera, rear_camera
from feelium.front_camera.service import FrontCameraService
from feelium.cameras.v4l2 import usb_camera_devices
from feelium.daemon.config import Config, parse_config
from feelium.hub import Hub


@pytest.fixture
def no_hardware(monkeypatch):
    monkeypatch.setattr(select, "camera_count", lambda: 0)
    monkeypatch.setattr("feelium.cameras.v4l2.usb_camera_devices", lambda: [])


def test_auto_without_hardware_is_sim(no_hardware):
    config = Config()
    assert select.resolve_rear_backend(config.rear_camera) == "sim"
    assert select.resolve_front_backend(config.front_camera)[0] == "sim"


def test_auto_prefers_the_pi_cameras_when_libcamera_sees_them(monkeypatch):
    monkeypatch.setattr(select, "camera_count", lambda: 2)
    config = Config()
    assert select.resolve_rear_backend(config.rear_camera) == "picamera2"
    assert select.resolve_front_backend(config.front_camera)[0] == "picamera2"


def test_auto_front_uses_a_usb_camera_when_only_that_is_there(monkeypatch):
    monkeypatch.setattr(select, "camera_count", lambda: 1)  # the rear camera only
    monkeypatch.setattr("feelium.cameras.v4l2.usb_camera_devices", lambda: ["/dev/video2"])
    assert select.resolve_front_backend(Config().front_camera) == ("v4l2", "/dev/video2")


def test_usb_cameras_are_found_by_their_uvc_driver_in_sysfs(tmp_path):
    drivers = tmp_path / "drivers"
    for name, driver, index in (("video0", "bcm2835-codec", "0"), ("video2", "uvcvideo", "0"), ("video3", "uvcvideo", "1")):
        (drivers / driver).mkdir(parents=True, exist_ok=True)
        node = tmp_path / "v4l" / name
        (node / "device").mkdir(parents=True)
        os.symlink(drivers / driver, node / "device" / "driver")
        (node / "index").write_text(index + "\n")
    assert usb_camera_devices(tmp_path / "v4l") == ["/dev/video2"]
    assert usb_camera_devices(tmp_path / "absent") == []


def test_off_builds_no_service():
    config = parse_config('[front_camera]\nbackend = "off"\n[rear_camera]\nbackend = "off"\n')
    assert build_front_camera(config, Hub()) is None
    assert rear_camera(config, lambda: 0.0) is None


def test_sim_front_service_is_built(no_hardware):
    service = build_front_camera(Config(), Hub())
    assert isinstance(service, FrontCameraService)
    assert service.source.backend == "sim"


def test_roi_config_errors_name_the_key():
    with pytest.raises(ValueError, match="rear_camera.roi"):
        parse_config("[rear_camera]\nroi = [1, 2, 3]\n", "x.toml")
    config = dataclasses.replace(
        Config(), rear_camera=dataclasses.replace(Config().rear_camera, backend="picamera2", roi=(600, 0, 100, 100))
    )
    with pytest.raises(ValueError, match="rear_camera.roi .* does not fit"):
        rear_camera(config, lambda: 0.0)
