"""Supervision: crashes are restarted with backoff while others run; shutdown is ordered and bounded."""

from __future__ import annotations

import asyncio
import logging
import time

from hypothesis import given
from hypothesis import strategies as st

from feelium.daemon.config import DaemonConfig
from feelium.daemon.supervisor import Supervisor, backoff_delay
from feelium.daemon import supervisor as supervisor_module

from .fakes import CrashingService, StubbornService, TickingService

FAST = DaemonConfig(restart_initial_s=0.01, restart_max_s=0.04, stop_timeout_s=0.1, shutdown_budget_s=0.5)


@given(
    st.integers(min_value=1, max_value=200),
    st.floats(min_value=0.01, max_value=10.0),
    st.floats(min_value=0.01, max_value=600.0),
)
def test_backoff_doubles_and_is_capped(failures, initial, maximum):
    delay = backoff_delay(failures, initial, maximum)
    assert 0 < delay <= maximum
    assert delay <= backoff_delay(failures + 1, initial, maximum)
    if failures == 1:
        assert delay == min(initial, maximum)
    if initial * 2 ** (failures - 1) < maximum:
        assert delay == initial * 2 ** (failures - 1)


async def _until(predicate, timeout=3.0):
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "condition not reached"
        await asyncio.sleep(0.005)


async def test_a_crashing_service_is_restarted_and_the_others_keep_running(caplog):
    steady = TickingService("steady")
    flaky = CrashingService(3, name="flaky")
    supervisor = Supervisor([steady, flaky], FAST)
    with caplog.at_level(logging.DEBUG):
        supervisor.start()
        await _until(lambda: supervisor.records["flaky"].crashes >= 1)
        report = supervisor.report()
        assert report["services"]["flaky"]["healthy"] is False or report["services"]["flaky"]["task"] == "running"
        await _until(lambda: flaky.runs == 4 and flaky.ticks > 3)
    report = supervisor.report()
    assert report["status"] == "ok"
    entry = report["services"]["flaky"]
    assert entry["crashes"] == 3 and entry["restarts"] == 3 and entry["last_crash"] == "RuntimeError: boom 3"
    assert entry["ticks"] > 0  # the service's own health is merged in
    ticks_during = steady.ticks
    assert ticks_during > 10  # kept ticking through the crashes
    crash_logs = [r for r in caplog.records if "flaky crashed" in r.getMessage()]
    assert len(crash_logs) == 3 and all(r.exc_info for r in crash_logs)  # logged with the traceback
    await supervisor.shutdown()


async def test_a_repeated_crash_logs_its_traceback_once_and_the_failure_once(caplog):
    """A camera that stays missing crashes its service every backoff: one warning with the traceback, one error."""

    class Missing(TickingService):
        async def run(self) -> None:
            raise OSError("no camera on CSI port 0")

    supervisor = Supervisor([Missing("touch"), TickingService("steady")], FAST)
    with caplog.at_level(logging.INFO):
        supervisor.start()
        await _until(lambda: supervisor.records["touch"].crashes >= 4 and supervisor.report() is not None)
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING and "touch crashed" in r.getMessage()]
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert len(warnings) == 1 and warnings[0].exc_info
    assert [r.getMessage() for r in errors] == [errors[0].getMessage()] and "touch: failed" in errors[0].getMessage()
    entry = supervisor.report()["services"]["touch"]
    assert entry["state"] == "failed" and "OSError: no camera on CSI port 0" in entry["reason"]
    assert entry["last_problem"] == entry["reason"]
    await supervisor.shutdown()


async def test_a_service_s_own_condition_and_last_error_are_kept():
    """The supervisor adds its fields beside the service's own; a running service that says it failed is failed."""

    class NoBoard(TickingService):
        def health(self):
            return {"condition": "failed", "reason": "no motor board", "last_error": "open /dev/ttyAMA0: gone"}

    supervisor = Supervisor([NoBoard("flight")], FAST, simulated={"flight": "flight on its simulator"})
    supervisor.start()
    await asyncio.sleep(0.02)
    entry = supervisor.report()["services"]["flight"]
    assert entry["state"] == "failed" and entry["reason"] == "no motor board"  # trouble beats "simulated"
    assert entry["last_error"] == "open /dev/ttyAMA0: gone" and entry["last_crash"] is None
    assert entry["simulated"] is True and entry["task"] == "running" and "condition" not in entry
    await supervisor.shutdown()


async def test_a_part_that_fails_to_build_is_retried_with_backoff_and_shown_failed_meanwhile(monkeypatch):
    attempts: list[float] = []
    delays: list[float] = []  # what the supervisor scheduled: wall-clock gaps only bound them from below on a busy machine
    real_delay = supervisor_module.backoff_delay
    monkeypatch.setattr(supervisor_module, "backoff_delay", lambda *a: delays.append(real_delay(*a)) or delays[-1])

    def build():
        attempts.append(time.monotonic())
        if len(attempts) < 3:
            raise OSError("no /dev/fb0")
        return TickingService("projector")

    supervisor = Supervisor(
        [TickingService("steady")], FAST, build_failures={"projector": "OSError: no /dev/fb0"}, rebuilders={"projector": build}
    )
    supervisor.start()
    entry = supervisor.report()["services"]["projector"]
    assert entry["state"] == "failed" and "no /dev/fb0" in entry["reason"] and "retrying in" in entry["reason"]
    await _until(lambda: "projector" in supervisor.records and supervisor.records["projector"].service.ticks > 0)
    gaps = [b - a for a, b in zip(attempts, attempts[1:])]
    assert len(attempts) == 3 and delays[1] == 2 * delays[0] and delays[2] == 2 * delays[1]  # the delay doubles
    assert all(gap >= delay - 1e-3 for gap, delay in zip(gaps, delays[1:]))  # and each retry waited it out
    report = supervisor.report()
    assert report["services"]["projector"]["state"] == "ok" and report["status"] == "ok"
    assert report["services"]["projector"]["last_problem"].startswith("cannot build: OSError: no /dev/fb0")
    await supervisor.shutdown()


async def test_a_crashing_service_is_reported_unhealthy_while_it_waits_to_restart():
    config = DaemonConfig(restart_initial_s=5.0, restart_max_s=5.0, stop_timeout_s=0.1, shutdown_budget_s=0.5)
    supervisor = Supervisor([CrashingService(1, name="flaky"), TickingService("steady")], config)
    supervisor.start()
    await _until(lambda: supervisor.records["flaky"].state == "backoff")
    report = supervisor.report()
    assert report["status"] == "degraded"
    assert report["services"]["flaky"]["healthy"] is False
    assert 4.0 < report["services"]["flaky"]["restart_in_s"] <= 5.0
    assert report["services"]["steady"]["healthy"] is True
    await supervisor.shutdown()
    assert supervisor.report()["status"] == "stopped"


async def test_give_up_after_consecutive_crashes():
    config = DaemonConfig(restart_initial_s=0.01, restart_max_s=0.01, give_up_after=2)
    supervisor = Supervisor([CrashingService(100, name="hopeless")], config)
    supervisor.start()
    await _until(lambda: supervisor.records["hopeless"].state == "failed")
    assert supervisor.records["hopeless"].crashes == 2
    await supervisor.shutdown()


async def test_shutdown_stops_in_ascending_stop_order_and_cancels_a_stubborn_service_within_budget():
    order: list[str] = []
    services = [
        TickingService("video", stop_order=50, log=order),
        StubbornService("stubborn", stop_order=10, log=order),
        TickingService("flight", stop_order=0, log=order),
    ]
    supervisor = Supervisor(services, FAST)
    supervisor.start()
    await asyncio.sleep(0.02)
    started = time.monotonic()
    await supervisor.shutdown()
    assert time.monotonic() - started < FAST.shutdown_budget_s + 0.2
    assert order == ["flight", "stubborn", "video"]
    assert all(r.task.done() for r in supervisor.records.values())
    assert {r.state for r in supervisor.records.values()} == {"stopped"}


async def test_a_service_that_returns_is_finished_not_restarted():
    class OneShot(TickingService):
        async def run(self) -> None:
            self.ticks += 1

    one = OneShot("oneshot")
    supervisor = Supervisor([one], FAST)
    supervisor.start()
    await _until(lambda: supervisor.records["oneshot"].state == "finished")
    await asyncio.sleep(0.05)
    report = supervisor.report()
    assert one.ticks == 1 and supervisor.records["oneshot"].starts == 1  # not restarted
    # ... but not healthy: every part is meant to run until shutdown (a replay that ended no longer senses)
    assert report["services"]["oneshot"]["state"] == "degraded" and report["services"]["oneshot"]["healthy"] is False
    assert "finished" in report["services"]["oneshot"]["reason"] and report["status"] == "degraded"
    await supervisor.shutdown()


async def test_health_that_raises_and_build_failures_are_reported_without_raising():
    class BadHealth(TickingService):
        def health(self):
            raise KeyError("oops")

    supervisor = Supervisor([BadHealth("bad")], FAST, build_failures={"feelium.x.service": "ImportError: nope"})
    supervisor.records["bad"].state = "running"
    report = supervisor.report()
    assert "KeyError" in report["services"]["bad"]["health_error"]
    assert report["services"]["bad"]["state"] == "degraded"
    built = report["services"]["feelium.x.service"]
    assert built["state"] == "failed" and built["healthy"] is False and built["last_error"] == "ImportError: nope"
    assert report["status"] != "ok"


def test_vital_alive_follows_the_flight_loop_heartbeat():
    class Flight(TickingService):
        vital = True

        def __init__(self):
            super().__init__("flight")
            self.beat = None

        def health(self):
            return {"heartbeat_at": self.beat}

    flight = Flight()
    supervisor = Supervisor([flight, TickingService("touch")], FAST, clock=lambda: 100.0)
    supervisor.records["flight"].state = "running"
    assert not supervisor.vital_alive(100.0, 1.0)  # no cycle yet, and no start recorded
    supervisor.records["flight"].started_at = 99.5  # started, first cycle not finished: as old as its start
    assert supervisor.vital_alive(100.0, 1.0)
    assert not supervisor.vital_alive(100.6, 1.0)  # ...and stalled once that is older than the heartbeat allows
    flight.beat = 99.5
    assert supervisor.vital_alive(100.0, 1.0)
    assert not supervisor.vital_alive(100.6, 1.0)
    supervisor.records["flight"].state = "backoff"
    assert not supervisor.vital_alive(99.6, 1.0)
    supervisor.records["touch"].state = "backoff"  # a camera fault is not the watchdog's business
    assert Supervisor([TickingService("touch")], FAST).vital_alive(0.0, 1.0)  # nothing vital: the loop is enough


async def test_a_failed_vital_part_fails_the_status_and_any_other_failure_degrades_it():
    """A monitor must tell a grounded blimp (flight failed) from a dropped camera frame (R15b F7)."""

    class Part(TickingService):
        def __init__(self, name: str, vital: bool = False) -> None:
            super().__init__(name)
            self.vital = vital
            self.condition = "ok"

        def health(self):
            return {"condition": self.condition, "reason": None if self.condition == "ok" else "no device"}

    flight, camera = Part("flight", vital=True), Part("camera")
    supervisor = Supervisor([flight, camera], FAST)
    supervisor.start()
    await _until(lambda: supervisor.report()["status"] == "ok")
    camera.condition = "failed"
    assert supervisor.report()["status"] == "degraded"
    flight.condition = "failed"
    report = supervisor.report()
    assert report["status"] == "failed" and report["services"]["flight"]["state"] == "failed"
    camera.condition = "ok"
    assert supervisor.report()["status"] == "failed"  # flight alone grounds the blimp
    flight.condition = "degraded"
    assert supervisor.report()["status"] == "degraded"
    await supervisor.shutdown()
