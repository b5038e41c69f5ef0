"""Keeps every service running: restarts crashes with backoff, reports health, shuts down in order.

Each service's ``run()`` is one task. An exception is logged with its
traceback, the service is reported unhealthy and restarted after a delay that
doubles on each crash in a row (capped; reset after a long healthy run); the
other services never notice. Shutdown calls ``stop()`` in ascending
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
from feelium.service import Service

log = logging.getLogger(__name__)


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
    last_error: str | None = None
    last_error_at: float | None = None
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
        extra_health: Callable[[], dict[str, Any]] | None = None,
    ) -> None:
        self.config = config
        self.clock = clock
        self.records = {s.name: ServiceRecord(s) for s in services}
        self.build_failures = dict(build_failures or {})
        self.extra_health = extra_health
        self.started_at = clock()
        self.phase = "starting"  # starting | running | stopping | stopped

    def start(self) -> None:
        """Start every service's task (call on the running loop)."""
        for record in self.records.values():
            record.task = asyncio.create_task(self._supervise(record), name=f"service:{record.service.name}")
        self.phase = "running"

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
                record.crashes += 1
                record.last_error = f"{type(exc).__name__}: {exc}"
                record.last_error_at = now
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
                log.error("service %s crashed (restart in %.2f s)", service.name, delay, exc_info=exc)
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

    def pipeline_alive(self, now: float, max_age_s: float) -> bool:
        """True while every critical service (the touch pipeline) has processed a frame within ``max_age_s``.

        With no critical service configured, the daemon's own loop being alive is enough.
        """
        for record in self.records.values():
            if not getattr(record.service, "critical", False):
                continue
            if record.state != "running":
                return False
            last = _safe_health(record.service).get("last_frame_at")
            if not isinstance(last, (int, float)) or now - last > max_age_s:
                return False
        return True

    def report(self) -> dict[str, Any]:
        """Per-service state, counters, rates and last error; ``ok`` when everything runs."""
        now = self.clock()
        services: dict[str, Any] = {}
        for name, record in self.records.items():
            entry: dict[str, Any] = _safe_health(record.service)
            entry.update({
                "state": record.state,
                "healthy": record.state in ("running", "finished"),
                "starts": record.starts,
                "restarts": max(0, record.starts - 1),
                "crashes": record.crashes,
                "last_error": record.last_error,
                "last_error_age_s": None if record.last_error_at is None else round(now - record.last_error_at, 3),
                "restart_in_s": None if record.restart_at is None else round(max(0.0, record.restart_at - now), 3),
            })
            services[name] = entry
        for module, error in self.build_failures.items():
            services[module] = {"state": "failed", "healthy": False, "last_error": error}
        healthy = all(s["healthy"] for s in services.values())
        report: dict[str, Any] = {
            "status": self.phase if self.phase != "running" else ("ok" if healthy else "degraded"),
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
