"""Overrides for --sim/--replay, discovery of service modules, the status line."""

from __future__ import annotations

import sys
import types

from feelium.config import Config, parse_config
from feelium.daemon.discovery import build_all, service_modules
from feelium.daemon.runner import status_line, with_overrides
from feelium.hub import Hub

from .fakes import TickingService


def test_sim_puts_every_part_with_a_backend_on_its_simulator_but_keeps_off_off():
    config = with_overrides(parse_config('[thermal]\nbackend = "off"\n'), sim=True)
    assert config.rear_camera.backend == "sim" and config.front_camera.backend == "sim"
    assert config.thermal.backend == "off"
    assert config.flight.backend == "sim"


def test_replay_sets_the_rear_camera_and_simulates_the_rest():
    config = with_overrides(Config(), replay="/data/s1")
    assert config.rear_camera.backend == "replay" and config.rear_camera.replay_path == "/data/s1"
    assert config.front_camera.backend == "sim"
    assert with_overrides(Config()) == Config()


def test_discovery_finds_the_camera_and_touch_services():
    modules = service_modules()
    assert "feelium.cameras.service" in modules and "feelium.touch.service" in modules


def test_a_module_that_fails_is_reported_and_the_rest_still_build(monkeypatch):
    good = types.ModuleType("feelium_test_good")
    good.build_services = lambda config, hub: [TickingService("good")]
    bad = types.ModuleType("feelium_test_bad")

    def explode(config, hub):
        raise OSError("no such bus")

    bad.build_services = explode
    notservice = types.ModuleType("feelium_test_notservice")
    notservice.build_services = lambda config, hub: [object()]
    for module in (good, bad, notservice):
        monkeypatch.setitem(sys.modules, module.__name__, module)
    found = build_all(Config(), Hub(), ["feelium_test_good", "feelium_test_bad", "feelium_test_notservice", "feelium_test_absent"])
    assert [s.name for s in found.services] == ["good"]
    assert found.failures["feelium_test_bad"] == "OSError: no such bus"
    assert "not a Service" in found.failures["feelium_test_notservice"]
    assert "ModuleNotFoundError" in found.failures["feelium_test_absent"]


def test_status_line_names_rates_and_trouble():
    report = {
        "status": "degraded",
        "services": {
            "touch": {"healthy": True, "fps": 14.96},
            "flight": {"healthy": False, "state": "backoff"},
            "http": {"healthy": True},
        },
    }
    assert status_line(report) == "degraded: touch 15.0 fps, flight backoff"
