"""Overrides for --sim/--replay, the assembly of services, the status line."""

from __future__ import annotations

import dataclasses
from typing import get_args, get_type_hints

from feelium.daemon.config import Config, parse_config
from feelium.daemon.assembly import SERVICES, build_services
from feelium.daemon.runner import status_line, with_overrides
from feelium.hub import Hub

from .fakes import TickingService


def test_sim_puts_every_part_with_a_backend_on_its_simulator_but_keeps_off_off():
    config = with_overrides(parse_config('[thermal]\nbackend = "off"\n'), sim=True)
    assert config.rear_camera.backend == "sim" and config.front_camera.backend == "sim"
    assert config.thermal.backend == "off"
    assert config.flight.backend == "sim"


def test_every_backend_choice_calls_its_simulated_part_sim():
    """One name for the no-hardware part (docs/architecture.md, Backends and sims)."""
    sections = get_type_hints(Config)
    with_backend = {}
    for field in dataclasses.fields(Config):
        hints = get_type_hints(sections[field.name])
        if "backend" in hints:
            with_backend[field.name] = set(get_args(hints["backend"]))
    assert {"rear_camera", "front_camera", "thermal", "flight", "projector", "audio"} <= set(with_backend)
    for name, choices in with_backend.items():
        assert "sim" in choices, name
        assert not choices & {"fake", "emulator", "emulated", "null"}, name


def test_replay_sets_the_rear_camera_and_simulates_the_rest():
    config = with_overrides(Config(), replay="/data/s1")
    assert config.rear_camera.backend == "replay" and config.rear_camera.replay_path == "/data/s1"
    assert config.front_camera.backend == "sim"
    assert with_overrides(Config()) == Config()


def test_the_assembly_lists_every_part_once_in_data_flow_order():
    parts = [part for part, _ in SERVICES]
    assert parts == ["touch", "front_camera", "thermal", "audio", "projector", "flight", "http"]


def test_the_simulated_blimp_builds_every_part(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no projector calibration here: the uncalibrated map
    config = with_overrides(parse_config(f'[http]\ntoken_file = "{tmp_path / "token"}"\n'), sim=True)
    built = build_services(config, Hub())
    assert built.failures == {}
    assert sorted(s.name for s in built.services) == sorted(["touch", "front_camera", "thermal", "audio", "projector", "flight", "http"])


def test_a_part_that_fails_is_reported_and_the_rest_still_build():
    def explode(config, hub):
        raise OSError("no such bus")

    built = build_services(
        Config(),
        Hub(),
        (
            ("good", lambda config, hub: TickingService("good")),
            ("bad", explode),
            ("notservice", lambda config, hub: object()),
            ("off", lambda config, hub: None),
            ("twin", lambda config, hub: TickingService("good")),
        ),
    )
    assert [s.name for s in built.services] == ["good"]
    assert built.failures["bad"] == "OSError: no such bus"
    assert "not a Service" in built.failures["notservice"]
    assert "off" not in built.failures
    assert "duplicate service name" in built.failures["twin"]


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


def test_the_pixel_parts_are_built_with_opencvs_pool_sized_as_configured():
    """``[daemon] opencv_threads`` is applied before any part that calls OpenCV is built (and starts threads)."""
    import asyncio

    import cv2

    from feelium.daemon.runner import _built_off_the_loop

    seen: list[int] = []

    def part(config: Config, hub: Hub) -> None:
        seen.append(cv2.getNumThreads())

    before = cv2.getNumThreads()
    try:
        for threads, expected in ((1, 1), (2, 2), (0, cv2.getNumberOfCPUs())):
            config = parse_config(f"[daemon]\nopencv_threads = {threads}\n")
            built = asyncio.run(_built_off_the_loop(config, Hub(), (("pixels", part),), asyncio.Event()))
            assert built is not None and not built.failures
            assert seen[-1] == expected
    finally:
        cv2.setNumThreads(before)


def test_feelium_run_makes_a_scratch_folder_only_for_a_replay_that_fits_its_map(monkeypatch):
    """Every run used to make an empty /tmp folder for a replay's fitted map, left behind whenever the process ended
    by ``os._exit`` (a stuck device thread) or a kill: 24 of them in one day's /tmp on the development machine."""
    import tempfile

    from feelium.cli import main
    from feelium.daemon import runner

    made: list[str] = []
    real = tempfile.TemporaryDirectory

    def recording(*args: object, **kwargs: object) -> tempfile.TemporaryDirectory:  # type: ignore[type-arg]
        made.append(str(kwargs.get("prefix")))
        return real(*args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(tempfile, "TemporaryDirectory", recording)
    monkeypatch.setattr(runner, "run_process", lambda config: 0)
    assert main(["run", "--sim"]) == 0
    assert made == []
