"""Flight health judges the board's sensors, not only its link: a board answering with a dead rangefinder is not ok."""

from __future__ import annotations

import asyncio
from dataclasses import replace

import pytest

from feelium.daemon.config import Config
from feelium.flight.sensor_health import FIRST_READINGS_S, FLOW_MISSING_S, sensor_problems
from feelium.flight.service import FlightService
from feelium.flight.sim_board import BoardParams, SensorParams, board_with
from feelium.hub import Hub
from tests.flight.test_service import RecordingSimOpener, stopped, wait_for

CONFIG = Config().flight
FRESH = {"range": 0.02, "heading": 0.02, "flow": 0.02}


def test_fresh_sensors_are_no_problem_and_a_link_just_up_is_given_its_first_readings() -> None:
    assert sensor_problems(FRESH, 10.0, CONFIG) == []
    assert sensor_problems({"range": None, "heading": None, "flow": None}, 0.5 * FIRST_READINGS_S, CONFIG) == []


def test_each_sensor_silent_past_its_limit_is_named_with_its_age_or_as_never_heard() -> None:
    dead_range = sensor_problems({**FRESH, "range": CONFIG.range_hold_s + 0.1}, 10.0, CONFIG)
    assert dead_range == [f"no rangefinder reading for {CONFIG.range_hold_s + 0.1:.1f} s: altitude failsafe, sinking gently"]
    assert sensor_problems({**FRESH, "range": CONFIG.range_hold_s - 0.01}, 10.0, CONFIG) == []  # a dropout it holds through
    never = sensor_problems({**FRESH, "flow": None}, 10.0, CONFIG)
    assert len(never) == 1 and never[0].startswith("no measured speed since the link came up")
    assert sensor_problems({**FRESH, "flow": 0.9 * FLOW_MISSING_S}, 10.0, CONFIG) == []  # a short gap does not flap
    both = sensor_problems({"range": 5.0, "heading": 5.0, "flow": 5.0}, 10.0, CONFIG)
    assert [problem.split(" ")[1] for problem in both] == ["rangefinder", "heading", "measured"]


async def test_a_board_whose_rangefinder_and_flow_report_nothing_is_degraded_and_says_why_and_ages_are_in_health() -> None:
    """The session-32 review: with every range reading out of range and no flow sensor, health said ok, link up,
    telemetry 13 ms old, while the controller flew ``altitude_failsafe`` on every tick."""
    hub = Hub()
    opener = RecordingSimOpener(CONFIG, 1, hub.clock)
    opener.params = board_with(BoardParams(sensors=SensorParams(range_dropout_probability=1.0, flow_fitted=False)),
                               z=CONFIG.sim.start_altitude_m)
    service = FlightService(CONFIG, hub, opener)
    task = asyncio.create_task(service.run())
    try:
        await wait_for(lambda: service.health()["condition"] == "degraded", timeout_s=2.0 + FIRST_READINGS_S)
        health = service.health()
        assert health["link"] == "up"
        assert "no rangefinder reading" in health["reason"] and "altitude failsafe" in health["reason"]
        assert "no measured speed since the link came up" in health["reason"]  # the board has no flow sensor at all
        ages = health["sensor_age_s"]
        assert ages["flow"] is None and ages["heading"] < 0.2
        assert ages["range"] is None or ages["range"] > CONFIG.range_hold_s  # the simulated board's power-up reading at most
    finally:
        await stopped(service, task)


async def test_a_board_whose_sensors_all_report_is_ok_with_each_sensors_age() -> None:
    hub = Hub()
    service = FlightService(CONFIG, hub, RecordingSimOpener(replace(CONFIG, sim=replace(CONFIG.sim, rangefinder_dropout=0.0)), 1, hub.clock))
    task = asyncio.create_task(service.run())
    try:
        await wait_for(lambda: service.cycles > 2 * CONFIG.rate_hz * FIRST_READINGS_S, timeout_s=5.0)
        health = service.health()
        assert health["condition"] == "ok", health.get("reason")
        assert all(0.0 <= age < 0.2 for age in health["sensor_age_s"].values())
    finally:
        await stopped(service, task)
