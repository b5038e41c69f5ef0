"""Start-up order: the flight loop flies first, and every other part is built off the event loop meanwhile.

A part's build can take long (imports, the simulated scene, the projector's maps, a device probe: about a second
here under load, several on a Pi). Before session 18 every part was built on the event loop before any started,
so the motors went uncommanded that long; these tests hold the order, not a timing: a build that waits for the
flight loop to fly could never finish under the old order.
"""

from __future__ import annotations

import asyncio
import dataclasses
import threading
import time
from typing import Any

import pytest

from feelium.daemon.assembly import SERVICES, STARTS_FIRST, build_flight
from feelium.daemon.config import Config
from feelium.daemon.runner import run_daemon
from feelium.daemon.sdnotify import Notifier
from feelium.daemon.supervisor import Supervisor
from feelium.flight.mixer import NEUTRAL, to_microseconds
from feelium.flight.service import FlightService
from feelium.hub import Hub
from feelium.settings import ConfigError

from .fakes import TickingService

NEUTRAL_US = to_microseconds(NEUTRAL)
FLIGHT_CYCLES = 25  # half a second of the 50 Hz loop
PATIENCE_S = 20.0  # how long a build waits for them: a deadline for a broken order, not a timing


def _config(**backends: str) -> Config:
    """The named parts on the given backends, every other part off (the projector has no off: sim)."""
    base = Config()
    sections = {"rear_camera": "off", "front_camera": "off", "thermal": "off", "audio": "off", "projector": "sim",
                "flight": "sim", **backends}  # fmt: skip
    changes: dict[str, Any] = {name: dataclasses.replace(getattr(base, name), backend=value) for name, value in sections.items()}
    changes["http"] = dataclasses.replace(base.http, enabled=False)
    changes["sim"] = dataclasses.replace(base.sim, autoplay=False)
    changes["daemon"] = dataclasses.replace(base.daemon, status_interval_s=60.0)
    return dataclasses.replace(base, **changes)


class FlightWatch:
    """Builds flight as the assembly does and keeps the service, so a build running meanwhile can watch it fly."""

    def __init__(self) -> None:
        self.service: FlightService | None = None

    def build(self, config: Config, hub: Hub) -> Any:
        self.service = build_flight(config, hub)  # type: ignore[assignment]
        return self.service

    def cycles(self) -> int:
        return 0 if self.service is None else self.service.cycles

    def wait_flying(self, cycles: int = FLIGHT_CYCLES, timeout_s: float = PATIENCE_S) -> int:
        """From a builder's thread: wait until the flight loop has cycled ``cycles`` times; the cycles seen."""
        deadline = time.monotonic() + timeout_s
        while self.cycles() < cycles and time.monotonic() < deadline:
            time.sleep(0.01)
        return self.cycles()


async def _run(config: Config, builders: Any, until: Any) -> Supervisor:
    """Run the daemon until the async ``until(supervisor)`` returns (at most ``PATIENCE_S`` after the start)."""
    stop = asyncio.Event()
    watching: list[asyncio.Future[None]] = []

    def started(hub: Hub, supervisor: Supervisor) -> None:
        async def watch() -> None:
            try:
                await asyncio.wait_for(until(supervisor), PATIENCE_S)
            finally:
                stop.set()

        watching.append(asyncio.ensure_future(watch()))

    return await run_daemon(config, stop=stop, hub=Hub(), builders=builders, notifier=Notifier({}), on_pi=False,
                            on_started=started)  # fmt: skip


async def test_the_flight_loop_flies_while_a_slow_part_builds() -> None:
    """A part listed before flight (as touch is) whose build lasts until the flight loop has flown half a second."""
    flight = FlightWatch()
    seen: dict[str, Any] = {}

    def slow(config: Config, hub: Hub) -> TickingService:
        seen["cycles"] = flight.wait_flying()
        seen["on_loop_thread"] = _on_a_loop_thread()
        return TickingService("slow")

    async def until(supervisor: Supervisor) -> None:
        while supervisor.records["slow"].service.ticks < 3:  # type: ignore[attr-defined]
            await asyncio.sleep(0.01)

    supervisor = await _run(_config(), (("slow", slow), ("flight", flight.build)), until)
    assert seen["cycles"] >= FLIGHT_CYCLES, f"flight cycled {seen['cycles']} times while the slow part was built"
    assert seen["on_loop_thread"] is False
    assert supervisor.records["slow"].starts == 1 and supervisor.records["flight"].crashes == 0


async def test_every_part_but_flight_is_built_off_the_event_loop() -> None:
    """The real assembly (the simulated rear camera, thermal and projector): flight is built first, on the loop
    before anything runs; every other part in a worker thread."""
    calls: list[tuple[str, bool]] = []

    def recorded(part: str, build: Any) -> Any:
        def wrapped(config: Config, hub: Hub) -> Any:
            calls.append((part, _on_a_loop_thread()))
            return build(config, hub)

        return wrapped

    async def until(supervisor: Supervisor) -> None:
        return None  # every part built and started: stop

    builders = tuple((part, recorded(part, build)) for part, build in SERVICES)
    supervisor = await _run(_config(rear_camera="sim", thermal="sim"), builders, until)
    assert STARTS_FIRST == {"flight"}
    assert calls[0] == ("flight", True)
    assert sorted(calls[1:]) == sorted((part, False) for part, _ in SERVICES if part != "flight")
    assert sorted(supervisor.records) == ["flight", "projector", "thermal", "touch"]  # audio, cameras, http: off


async def test_a_stop_while_parts_build_stops_flight_at_once_and_starts_nothing_else() -> None:
    flight = FlightWatch()
    release = threading.Event()
    stop = asyncio.Event()

    def stuck(config: Config, hub: Hub) -> TickingService:
        release.wait(PATIENCE_S)  # a device probe that hangs
        return TickingService("stuck")

    async def stop_once_flying() -> None:
        while flight.cycles() < 5:
            await asyncio.sleep(0.01)
        stop.set()

    stopper = asyncio.ensure_future(stop_once_flying())
    try:
        supervisor = await asyncio.wait_for(
            run_daemon(_config(), stop=stop, hub=Hub(), builders=(("stuck", stuck), ("flight", flight.build)),
                       notifier=Notifier({}), on_pi=False),  # fmt: skip
            PATIENCE_S / 2,
        )
    finally:
        release.set()
        stopper.cancel()
    assert list(supervisor.records) == ["flight"] and supervisor.records["flight"].state == "stopped"
    assert flight.service is not None and _neutral_and_closed(flight.service)


async def test_a_config_error_found_after_flight_started_stops_it_neutral_and_is_raised() -> None:
    flight = FlightWatch()

    def wrong(config: Config, hub: Hub) -> None:
        flight.wait_flying(5)
        raise ConfigError("config", "http.tls_cert", "not a PEM certificate")

    with pytest.raises(ConfigError, match="tls_cert"):
        await run_daemon(_config(), hub=Hub(), builders=(("http", wrong), ("flight", flight.build)),
                         notifier=Notifier({}), on_pi=False)  # fmt: skip
    assert flight.service is not None and flight.service.cycles >= 5 and _neutral_and_closed(flight.service)


def _on_a_loop_thread() -> bool:
    """Whether this code runs on a thread with a running event loop (the daemon's)."""
    try:
        asyncio.get_running_loop()
    except RuntimeError:
        return False
    return True


def _neutral_and_closed(service: FlightService) -> bool:
    board = service.opener.board  # type: ignore[attr-defined]
    return board is not None and tuple(board.motors_us) == NEUTRAL_US and service.link is None
