"""Flight health says when the body is outside its altitude limits: after a fault the body can sit over the ceiling
limit with the link up and every sensor fresh, and health said ok (docs/flight-robustness.md, session 35)."""

from __future__ import annotations

import asyncio

from feelium.daemon.config import Config
from feelium.flight.altitude_health import OUTSIDE_REPORTED_M, AltitudeWatch
from feelium.flight.sensor_health import CLEAR_AFTER_S
from feelium.flight.service import FlightService
from feelium.flight.sim_board import BoardParams, board_with
from feelium.hub import Hub
from tests.flight.test_service import RecordingSimOpener, stopped, wait_for

CONFIG = Config().flight
HIGH, LOW = CONFIG.altitude_max_m, CONFIG.altitude_min_m


def test_inside_or_within_the_goal_s_tolerance_of_a_limit_is_no_problem_and_no_estimate_is_another_report_s() -> None:
    watch = AltitudeWatch(CONFIG)
    for z in (0.5 * (LOW + HIGH), HIGH + 0.9 * OUTSIDE_REPORTED_M, LOW - 0.9 * OUTSIDE_REPORTED_M, None, float("nan")):
        assert watch.problems(10.0, z) == []


def test_past_a_limit_by_more_than_the_goal_allows_is_reported_with_how_far_and_which() -> None:
    over = AltitudeWatch(CONFIG).problems(10.0, HIGH + 0.25)
    assert over == [f"altitude {HIGH + 0.25:.2f} m: 0.25 m over the ceiling limit ({HIGH:.2f} m)"]
    under = AltitudeWatch(CONFIG).problems(10.0, LOW - 0.2)
    assert under == [f"altitude {LOW - 0.2:.2f} m: 0.20 m under the floor limit ({LOW:.2f} m)"]


def test_an_excursion_stays_reported_until_the_body_has_been_back_a_while_so_health_does_not_flap() -> None:
    watch = AltitudeWatch(CONFIG)
    watch.problems(10.0, HIGH + 0.3)
    assert watch.problems(11.0, HIGH) == ["altitude was 0.30 m over the ceiling limit 1.0 s ago"]
    assert watch.problems(10.0 + CLEAR_AFTER_S, HIGH) == []
    assert watch.problems(20.0, HIGH) == []


def test_a_body_a_partner_holds_outside_the_limits_is_not_a_fault() -> None:
    assert AltitudeWatch(CONFIG).problems(10.0, LOW - 0.3, held=True) == []


async def test_a_blimp_over_its_ceiling_limit_with_the_link_up_is_degraded_and_says_where() -> None:
    hub = Hub()
    opener = RecordingSimOpener(CONFIG, 1, hub.clock)
    opener.params = board_with(BoardParams(), z=HIGH + 0.35)
    service = FlightService(CONFIG, hub, opener)
    task = asyncio.create_task(service.run())
    try:
        await wait_for(lambda: "ceiling limit" in service.health().get("reason", ""), timeout_s=3.0)
        health = service.health()
        assert health["condition"] == "degraded" and health["link"] == "up"
    finally:
        await stopped(service, task)
