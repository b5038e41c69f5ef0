"""Supervision: crashes are restarted with backoff while others run; shutdown is ordered and bounded."""

from __future__ import annotations

import asyncio
import logging
import time

from hypothesis import given
from hypothesis import strategies as st

from feelium.daemon.config import DaemonConfig
from feelium.daemon.supervisor import Supervisor, backoff_delay

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
    with caplog.at_level(logging.ERROR):
        supervisor.start()
        await _until(lambda: supervisor.records["flaky"].crashes >= 1)
        report = supervisor.report()
        assert report["services"]["flaky"]["healthy"] is False or report["services"]["flaky"]["state"] == "running"
        await _until(lambda: flaky.runs == 4 and flaky.ticks > 3)
    report = supervisor.report()
    assert report["status"] == "ok"
    entry = report["services"]["flaky"]
    assert entry["crashes"] == 3 and entry["restarts"] == 3 and entry["last_error"] == "RuntimeError: boom 3"
    assert entry["ticks"] > 0  # the service's own health is merged in
    ticks_during = steady.ticks
    assert ticks_during > 10  # kept ticking through the crashes
    crash_logs = [r for r in caplog.records if "flaky crashed" in r.getMessage()]
    assert len(crash_logs) == 3 and all(r.exc_info for r in crash_logs)  # logged with the traceback
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
    assert one.ticks == 1 and supervisor.report()["services"]["oneshot"]["healthy"] is True
    await supervisor.shutdown()


async def test_health_that_raises_and_build_failures_are_reported_without_raising():
    class BadHealth(TickingService):
        def health(self):
            raise KeyError("oops")

    supervisor = Supervisor([BadHealth("bad")], FAST, build_failures={"feelium.x.service": "ImportError: nope"})
    report = supervisor.report()
    assert "KeyError" in report["services"]["bad"]["health_error"]
    assert report["services"]["feelium.x.service"] == {"state": "failed", "healthy": False, "last_error": "ImportError: nope"}
    assert report["status"] != "ok"


def test_pipeline_alive_follows_the_critical_services_last_frame():
    class Camera(TickingService):
        critical = True

        def __init__(self):
            super().__init__("touch")
            self.last = None

        def health(self):
            return {"last_frame_at": self.last}

    camera = Camera()
    supervisor = Supervisor([camera, TickingService("other")], FAST, clock=lambda: 100.0)
    supervisor.records["touch"].state = "running"
    assert not supervisor.pipeline_alive(100.0, 2.0)  # no frame yet
    camera.last = 99.0
    assert supervisor.pipeline_alive(100.0, 2.0)
    assert not supervisor.pipeline_alive(102.5, 2.0)
    supervisor.records["touch"].state = "backoff"
    assert not supervisor.pipeline_alive(99.5, 2.0)
    assert Supervisor([TickingService()], FAST).pipeline_alive(0.0, 1.0)  # nothing critical: alive
