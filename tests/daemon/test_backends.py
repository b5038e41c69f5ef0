"""What ``auto`` means: the hardware on a Raspberry Pi (never a silent simulator), the simulator elsewhere."""

from __future__ import annotations

from feelium.daemon.backends import on_raspberry_pi, resolve_auto, simulated_parts
from feelium.daemon.config import parse_config


def test_the_board_is_recognised_from_the_device_tree_model(tmp_path):
    model = tmp_path / "model"
    model.write_bytes(b"Raspberry Pi Zero 2 W Rev 1.0\x00")
    assert on_raspberry_pi(model)
    model.write_bytes(b"Radxa ZERO 3\x00")
    assert not on_raspberry_pi(model)
    assert not on_raspberry_pi(tmp_path / "absent")  # a laptop has no device tree


def test_on_a_pi_auto_is_the_hardware_and_nothing_is_simulated():
    config = resolve_auto(parse_config('[front_camera]\ndevice = "/dev/video7"\n'), on_pi=True)
    assert config.rear_camera.backend == "picamera2"
    assert config.thermal.backend == "smbus2"
    assert config.flight.backend == "serial"
    assert config.projector.backend == "fbdev"
    assert config.audio.backend == "alsa"
    assert config.front_camera.backend in ("picamera2", "v4l2") and config.front_camera.backend != "sim"
    assert simulated_parts(config) == {}


def test_off_a_pi_auto_is_the_simulator_and_explicit_choices_stay():
    config = resolve_auto(parse_config('[flight]\nbackend = "serial"\n[thermal]\nbackend = "off"\n'), on_pi=False)
    assert config.rear_camera.backend == "sim" and config.projector.backend == "sim"
    assert config.flight.backend == "serial" and config.thermal.backend == "off"
    parts = simulated_parts(config)
    assert set(parts) == {"touch", "front_camera", "audio", "projector"}
    assert parts["touch"] == "rear_camera on its simulator"


def test_sim_is_simulated_even_on_a_pi_and_a_replay_counts_as_simulated():
    config = resolve_auto(parse_config('[audio]\nbackend = "sim"\n[rear_camera]\nbackend = "replay"\nreplay_path = "/data/s1"\n'), True)
    assert config.audio.backend == "sim"
    assert simulated_parts(config) == {"audio": "audio on its simulator", "touch": "rear_camera replays /data/s1"}
