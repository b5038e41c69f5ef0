"""Keeps every service running: restarts crashes with backoff, reports health, shuts down in order.

Each service's ``run()`` is one task. An exception is logged with its
traceback (once per kind of crash: a device that stays missing does not fill
the journal), the service is reported failed and restarted after a delay that
doubles on each crash in a row (capped; reset after a long healthy run); the
other services never notice. A part that could not even be built is retried
the same way, shown as failed meanwhile. Shutdown calls ``stop()`` in ascending
``stop_order`` (flight first, so the motors are safe before anything else
goes), each with a timeout, then cancels whatever is still running, all
within a fixed budget.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from feelium.daemon.config import DaemonConfig
from feelium.daemon.health import HealthTracker, judge, overall
from feelium.service import Service

log = logging.getLogger(__name__)


ServiceFactory = Callable[[], "Service | None"]


def backoff_delay(failures: int, initial: float, maximum: float) -> float:
    """Delay before restart number ``failures`` (1-based) of a crash streak: initial, 2x, 4x ... capped."""
    if failures < 1:
        return 0.0
    return min(maximum, initial * 2.0 ** min(failures - 1, 60))


@dataclass
class ServiceRecord:
    """What the supervisor knows about one service."""

    service: Service
    state: str = "starting"  # starting | running | backoff | finished | failed | stopped
    starts: int = 0
    crashes: int = 0
    streak: int = 0
    last_crash: str | None = None
    last_crash_at: float | None = None
    started_at: float | None = None
    restart_at: float | None = None
    task: asyncio.Task[None] | None = None


class Supervisor:
    """Runs services as tasks; ``report()`` is what ``hub.health()`` returns."""

    def __init__(
        self,
        services: list[Service],
        config: DaemonConfig,
        *,
        clock: Callable[[], float] = time.monotonic,
        build_failures: dict[str, str] | None = None,
        rebuilders: dict[str, ServiceFactory] | None = None,
        simulated: dict[str, str] | None = None,
        extra_health: Callable[[], dict[str, Any]] | None = None,
    ) -> None:
        """``rebuilders``: per part that failed to build, how to try again; ``simulated``: part -> which simulator."""
        self.config = config
        self.clock = clock
        self.records = {s.name: ServiceRecord(s) for s in services}
        self.build_failures = dict(build_failures or {})
        self.rebuilders = dict(rebuilders or {})
        self.rebuild_at: dict[str, float] = {}
        self.simulated = dict(simulated or {})
        self.extra_health = extra_health
        self.tracker = HealthTracker(clock)
        self.started_at = clock()
        self.phase = "starting"  # starting | running | stopping | stopped
        self._rebuild_tasks: list[asyncio.Task[None]] = []

    def start(self) -> None:
        """Start every service's task and the retries of parts that failed to build (call on the running loop)."""
        for record in self.records.values():
            self._launch(record)
        for part, build in self.rebuilders.items():
            if part in self.build_failures:
                self._start_rebuild(part, build)
        self.phase = "running"

    def add(self, services: list[Service], build_failures: dict[str, str], rebuilders: dict[str, ServiceFactory]) -> None:
        """Start parts built after :meth:`start` (the daemon starts the flight loop first and builds the rest
        meanwhile); a part that failed to build is retried as at the start. Nothing starts once stopping."""
        if self.phase != "running":
            return
        for service in services:
            if service.name in self.records:
                self.build_failures[service.name] = f"duplicate service name {service.name!r}"
                log.warning("cannot add %s: duplicate service name", service.name)
                continue
            record = self.records[service.name] = ServiceRecord(service)
            self._launch(record)
        self.build_failures.update(build_failures)
        for part, build in rebuilders.items():
            if part in build_failures:
                self._start_rebuild(part, build)

    def _start_rebuild(self, part: str, build: ServiceFactory) -> None:
        self._schedule_rebuild(part, 1)
        self._rebuild_tasks.append(asyncio.create_task(self._rebuild(part, build), name=f"rebuild:{part}"))

    def _launch(self, record: ServiceRecord) -> None:
        record.task = asyncio.create_task(self._supervise(record), name=f"service:{record.service.name}")

    def _schedule_rebuild(self, part: str, attempt: int) -> None:
        self.rebuild_at[part] = self.clock() + backoff_delay(attempt, self.config.restart_initial_s, self.config.restart_max_s)

    async def _rebuild(self, part: str, build: ServiceFactory) -> None:
        """Build a part again after a doubling delay until it builds; it is reported failed meanwhile."""
        attempt = 1
        while True:
            await asyncio.sleep(max(0.0, self.rebuild_at[part] - self.clock()))
            if self.phase != "running":
                return
            previous = self.build_failures.get(part)
            try:
                # in a thread: a first import or a device probe on the Pi must not hold the flight loop up
                service = await asyncio.to_thread(build)
            except Exception as exc:
                error = f"{type(exc).__name__}: {exc}"
                self.build_failures[part] = error
                log.log(logging.DEBUG if error == previous else logging.WARNING, "cannot build %s again: %s", part, error)
                attempt += 1
                self._schedule_rebuild(part, attempt)
                continue
            del self.build_failures[part]
            self.rebuild_at.pop(part, None)
            if service is None or self.phase != "running":
                return
            if service.name in self.records:
                self.build_failures[part] = f"duplicate service name {service.name!r}"
                return
            log.info("%s built at attempt %d", part, attempt + 1)
            record = self.records[service.name] = ServiceRecord(service)
            self._launch(record)
            return

    async def _supervise(self, record: ServiceRecord) -> None:
        cfg = self.config
        service = record.service
        while True:
            record.state = "running"
            record.starts += 1
            record.started_at = self.clock()
            record.restart_at = None
            try:
                await service.run()
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                now = self.clock()
                error = f"{type(exc).__name__}: {exc}"
                repeated = error == record.last_crash
                record.crashes += 1
                record.last_crash = error
                record.last_crash_at = now
                if record.started_at is not None and now - record.started_at >= cfg.healthy_after_s:
                    record.streak = 0
                record.streak += 1
                if self.phase != "running":
                    record.state = "stopped"
                    return
                if cfg.give_up_after and record.streak >= cfg.give_up_after:
                    record.state = "failed"
                    log.error("service %s crashed %d times in a row; giving up", service.name, record.streak, exc_info=exc)
                    return
                delay = backoff_delay(record.streak, cfg.restart_initial_s, cfg.restart_max_s)
                record.state = "backoff"
                record.restart_at = now + delay
                # the traceback once per kind of crash; the part's change to failed is logged by the health tracker
                level = logging.DEBUG if repeated else logging.WARNING
                log.log(level, "service %s crashed (restart in %.2f s)", service.name, delay, exc_info=exc)
                await asyncio.sleep(delay)
                continue
            record.state = "finished" if self.phase == "running" else "stopped"
            log.info("service %s %s", service.name, record.state)
            return

    async def shutdown(self) -> None:
        """Stop everything within ``shutdown_budget_s``: ``stop()`` by ascending ``stop_order``, then cancel."""
        if self.phase in ("stopping", "stopped"):
            return
        self.phase = "stopping"
        for rebuild in self._rebuild_tasks:
            rebuild.cancel()
        cfg = self.config
        loop = asyncio.get_running_loop()
        deadline = loop.time() + cfg.shutdown_budget_s
        ordered = sorted(self.records.values(), key=lambda r: (r.service.stop_order, r.service.name))
        for record in ordered:
            remaining = deadline - loop.time()
            if remaining <= 0:
                log.warning("shutdown budget spent before stopping %s; cancelling it", record.service.name)
                continue
            try:
                await asyncio.wait_for(record.service.stop(), min(cfg.stop_timeout_s, remaining))
            except asyncio.TimeoutError:
                log.warning("service %s did not stop within %.2f s; cancelling it", record.service.name, cfg.stop_timeout_s)
            except Exception:
                log.exception("service %s failed while stopping", record.service.name)
        tasks = [r.task for r in ordered if r.task is not None and not r.task.done()]
        if tasks:
            # give run() a moment to return by itself after stop(), then cancel the rest
            await asyncio.wait(tasks, timeout=max(0.0, min(0.2, deadline - loop.time())))
        for task in tasks:
            task.cancel()
        pending = [t for t in tasks if not t.done()]
        if pending:
            done, still = await asyncio.wait(pending, timeout=max(0.05, deadline - loop.time()))
            for task in still:
                log.warning("task %s ignored cancellation; leaving it", task.get_name())
        for record in ordered:
            if record.state in ("running", "backoff", "starting"):
                record.state = "stopped"
            if record.task is not None and record.task.done() and not record.task.cancelled():
                exc = record.task.exception()
                if exc is not None and not isinstance(exc, asyncio.CancelledError):
                    log.error("service %s ended with %s", record.service.name, exc)
        self.phase = "stopped"

    def vital_names(self) -> frozenset[str]:
        """The services the blimp cannot do without (the flight loop): one of them failed fails the whole status."""
        return frozenset(name for name, record in self.records.items() if getattr(record.service, "vital", False))

    def vital_alive(self, now: float, max_age_s: float) -> bool:
        """True while every vital service (the flight loop) runs and its heartbeat is at most ``max_age_s`` old.

        This is what feeds the systemd watchdog: the daemon is restarted for a
        stuck flight loop (or a stuck event loop, which stops this check from
        running at all), never for a camera, thermal, audio or projector fault.
        A loop that has just started and not finished its first cycle is given the same ``max_age_s`` from
        its start: which of the two tasks runs first after a start is the event loop's choice, not a stall.
        """
        for record in self.records.values():
            if not getattr(record.service, "vital", False):
                continue
            if record.state != "running":
                return False
            beat = _safe_health(record.service).get("heartbeat_at")
            if not isinstance(beat, (int, float)):
                beat = record.started_at  # no cycle yet: as old as the start
            if beat is None or now - beat > max_age_s:
                return False
        return True

    def report(self) -> dict[str, Any]:
        """Per part: its state (ok, simulated, degraded, failed, starting, stopped), why, since when, and counters."""
        now = self.clock()
        services: dict[str, Any] = {}
        for name, record in self.records.items():
            entry: dict[str, Any] = _safe_health(record.service)
            retry_in = None if record.restart_at is None else max(0.0, record.restart_at - now)
            state, reason = judge(record.state, entry, self.simulated.get(name), record.last_crash, retry_in)
            current = self.tracker.parts.get(name)
            if state == "starting" and current is not None and current.state == "failed":
                state, reason = "failed", current.reason  # a restart is no recovery until the part works again
            if "health_error" in entry and state in ("ok", "simulated"):
                state, reason = "degraded", f"health() failed: {entry['health_error']}"
            self.tracker.update(name, state, reason)
            entry.pop("condition", None)
            entry.update(self.tracker.entry(name))
            entry.update({
                "task": record.state,
                "simulated": name in self.simulated,
                "starts": record.starts,
                "restarts": max(0, record.starts - 1),
                "crashes": record.crashes,
                "last_crash": record.last_crash,
                "last_crash_age_s": None if record.last_crash_at is None else round(now - record.last_crash_at, 3),
                "restart_in_s": None if retry_in is None else round(retry_in, 3),
            })
            services[name] = entry
        for part, error in self.build_failures.items():
            retry_at = self.rebuild_at.get(part)
            retry = "" if retry_at is None else f"; retrying in {max(0.0, retry_at - now):.1f} s"
            self.tracker.update(part, "failed", f"cannot build: {error}{retry}")
            services[part] = {**self.tracker.entry(part), "task": "unbuilt", "simulated": part in self.simulated, "last_error": error}
        phase = self.phase
        report: dict[str, Any] = {
            "status": phase if phase != "running" else overall({n: s["state"] for n, s in services.items()}, self.vital_names()),
            "uptime_s": round(now - self.started_at, 3),
            "services": services,
        }
        if self.extra_health is not None:
            report.update(self.extra_health())
        return report


def _safe_health(service: Service) -> dict[str, Any]:
    try:
        value = service.health()
        return dict(value) if isinstance(value, dict) else {"health_error": f"health() returned {type(value).__name__}"}
    except Exception as exc:  # health must never take the report down
        return {"health_error": f"{type(exc).__name__}: {exc}"}
