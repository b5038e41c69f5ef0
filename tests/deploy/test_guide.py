"""docs/deploy.md and config/feelium.service tell the same story, and every pip step on the Pi is constrained."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GUIDE = (ROOT / "docs" / "deploy.md").read_text(encoding="utf-8")
UNIT = (ROOT / "config" / "feelium.service").read_text(encoding="utf-8")


def _unit(key: str) -> str:
    match = re.search(rf"^{key}=(.*)$", UNIT, re.MULTILINE)
    assert match, f"config/feelium.service has no {key}="
    return match.group(1).strip()


def test_every_pip_install_on_the_pi_uses_the_constraints():
    steps = [line for line in GUIDE.splitlines() if re.search(r"venv/bin/pip install", line)]
    assert steps, "the guide installs nothing with the venv's pip"
    for line in steps:
        assert "-c /opt/feelium/src/constraints/pi-bookworm.txt" in line, line
    assert (ROOT / "constraints" / "pi-bookworm.txt").is_file()


def test_the_venv_sees_the_system_camera_modules():
    assert "python3 -m venv --system-site-packages /opt/feelium/venv" in GUIDE
    assert _unit("ExecStart").startswith("/opt/feelium/venv/bin/feelium run")


def test_the_user_home_is_the_units_state_directory_and_its_groups_match():
    useradd = re.search(r"useradd (.*?)feelium\n", GUIDE.replace("\\\n", " "), re.DOTALL)
    assert useradd, "the guide creates no feelium user"
    options = useradd.group(1)
    assert "--create-home" in options and f"--home-dir /var/lib/{_unit('StateDirectory')}" in options
    groups = set(re.search(r"--groups (\S+)", options).group(1).split(","))  # type: ignore[union-attr]
    assert groups == set(_unit("SupplementaryGroups").split())
    assert {"video", "i2c", "dialout", "gpio", "audio"} <= groups


def test_i2c_dev_serial_and_the_headset_link_are_set_up():
    assert "echo i2c-dev | sudo tee /etc/modules-load.d/" in GUIDE
    assert "raspi-config nonint do_serial_cons 1" in GUIDE and "enable_uart=1" in GUIDE
    assert 'host = "0.0.0.0"' in GUIDE
    assert "/var/lib/feelium/.config/feelium/http-token" in GUIDE
    default_token = (ROOT / "config" / "feelium.toml").read_text(encoding="utf-8")
    assert 'token_file = "~/.config/feelium/http-token"' in default_token  # the path the guide names


def test_the_unit_gives_the_daemon_room_for_its_bounded_streams():
    """The link bounds its streams (16 MJPEG, 8 speech, 64 event streams) below the descriptors it has."""
    from feelium.http.config import HttpConfig

    limit = int(_unit("LimitNOFILE"))
    config = HttpConfig()
    assert limit >= 4 * (config.max_stream_clients + config.max_speech_streams + config.max_event_streams)
