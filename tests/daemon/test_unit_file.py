"""config/feelium.service has what the blimp needs: notify + watchdog, a start limit, its user and groups, its devices."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from feelium.daemon.config import Config

UNIT = Path(__file__).resolve().parents[2] / "config" / "feelium.service"


def parse_unit(text: str) -> dict[str, dict[str, list[str]]]:
    """systemd's ini dialect: sections of keys that may repeat (every value kept, in order)."""
    sections: dict[str, dict[str, list[str]]] = {}
    current = None
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith(("#", ";")):
            continue
        if line.startswith("[") and line.endswith("]"):
            current = sections.setdefault(line[1:-1], {})
            continue
        assert current is not None and "=" in line, f"line {number} is not key=value inside a section: {raw!r}"
        key, _, value = line.partition("=")
        current.setdefault(key.strip(), []).append(value.strip())
    return sections


@pytest.fixture(scope="module")
def unit() -> dict[str, dict[str, list[str]]]:
    return parse_unit(UNIT.read_text(encoding="utf-8"))


def one(unit, section: str, key: str) -> str:
    values = unit[section].get(key)
    assert values, f"[{section}] {key}= is missing"
    return values[-1]


def seconds(value: str) -> float:
    units = {"ms": 0.001, "s": 1.0, "min": 60.0, "": 1.0}
    number = value.rstrip("abcdefghijklmnopqrstuvwxyz")
    return float(number) * units[value[len(number):]]


def test_notify_with_a_watchdog_longer_than_the_flight_heartbeat_limit(unit):
    assert one(unit, "Service", "Type") == "notify"
    assert one(unit, "Service", "NotifyAccess") == "main"
    watchdog = seconds(one(unit, "Service", "WatchdogSec"))
    assert watchdog > 2 * Config().daemon.flight_heartbeat_s  # a healthy flight loop is never killed by its own limit
    assert seconds(one(unit, "Service", "TimeoutStopSec")) > Config().daemon.shutdown_budget_s


def test_restarts_on_failure_with_a_deliberate_start_limit(unit):
    assert one(unit, "Service", "Restart") == "on-failure"
    assert seconds(one(unit, "Unit", "StartLimitIntervalSec")) > 0
    assert int(one(unit, "Unit", "StartLimitBurst")) >= 2
    assert seconds(one(unit, "Service", "RestartSec")) * int(one(unit, "Unit", "StartLimitBurst")) < seconds(
        one(unit, "Unit", "StartLimitIntervalSec")
    )  # the limit can actually trip


def test_runs_as_its_own_user_with_the_device_groups(unit):
    assert one(unit, "Service", "User") == "feelium"
    groups = set(" ".join(unit["Service"]["SupplementaryGroups"]).split())
    assert {"video", "i2c", "dialout", "gpio"} <= groups
    assert one(unit, "Service", "ExecStart").endswith("feelium run --config /etc/feelium/feelium.toml")
    assert one(unit, "Install", "WantedBy") == "multi-user.target"


def test_hardened_but_the_devices_stay_reachable(unit):
    service = unit["Service"]
    for key, value in {
        "NoNewPrivileges": "yes",
        "ProtectSystem": "strict",
        "ProtectHome": "yes",
        "PrivateTmp": "yes",
        "ProtectKernelModules": "yes",
        "RestrictSUIDSGID": "yes",
        "DevicePolicy": "closed",
    }.items():
        assert one(unit, "Service", key) == value, key
    assert service.get("PrivateDevices", ["no"])[-1] != "yes"  # would hide /dev/video*, /dev/i2c-*, ...
    allowed = {v.split()[0] for v in service["DeviceAllow"]}
    needed = {
        "char-video4linux": "/dev/video*",
        "char-media": "/dev/media* (libcamera)",
        "char-dma_heap": "/dev/dma_heap/* (libcamera buffers)",
        "char-i2c": "/dev/i2c-*",
        "char-ttyAMA": "/dev/ttyAMA0, /dev/serial0",
        "char-ttyS": "/dev/ttyS0 (mini UART behind /dev/serial0)",
        "char-fb": "/dev/fb0",
        "char-drm": "/dev/dri/*",
        "char-alsa": "/dev/snd/*",
    }
    missing = {k: v for k, v in needed.items() if k not in allowed}
    assert not missing, f"devices the daemon cannot reach: {missing}"
    assert all(v.split()[1] == "rw" for v in service["DeviceAllow"])
    assert "AF_INET" in one(unit, "Service", "RestrictAddressFamilies").split()  # the HTTP server


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="systemd-analyze not installed")
def test_systemd_accepts_the_unit():
    done = subprocess.run(
        ["systemd-analyze", "verify", str(UNIT)], capture_output=True, text=True, timeout=60, check=False
    )
    problems = [
        line
        for line in (done.stdout + done.stderr).splitlines()
        if line.strip() and "is not executable" not in line  # the venv exists only on the blimp
    ]
    assert not problems, "\n".join(problems)
