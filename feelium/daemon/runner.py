"""``feelium run``: build the services, supervise them, talk to systemd, stop cleanly on a signal.

Every way the process can end on its own terms goes through the supervisor's
shutdown, which sets the motors neutral first: SIGTERM, SIGINT, SIGHUP and
SIGQUIT (all four mean "stop": a reload would have to rebuild half the
daemon, and ``systemctl restart`` already does that with the motors
neutral), and an exception escaping the daemon's own loop. SIGKILL and
SIGABRT cannot be caught (SIGABRT is also what systemd's watchdog sends):
the motor board's own 300 ms watchdog sets the motors neutral then.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, get_args, get_type_hints

from feelium.daemon.config import PI_BACKGROUND_NICE, Config
from feelium.daemon.assembly import SERVICES, STARTS_FIRST, Built, ServiceBuilder, build_services
from feelium.daemon.backends import backend_names, on_raspberry_pi, resolve_auto, simulated_parts
from feelium.daemon.eventloop import loop_kind, new_event_loop
from feelium.daemon.memory import FreeMemoryReturner, tune_malloc
from feelium.daemon.sdnotify import Notifier
from feelium.daemon.supervisor import Supervisor
from feelium.hub import Hub
from feelium.priority import background_nice, lower_current_thread, set_background_nice
from feelium.service import Service
from feelium.settings import ConfigError

log = logging.getLogger(__name__)

SIM_BACKEND = "sim"  # every section's no-hardware backend (docs/architecture.md: Backends and sims)
WORKER_THREADS = 8  # camera reads, the touch pipeline, overlays, other services' blocking calls
STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT)


def _has_sim_backend(section: Any) -> bool:
    """Whether ``sim`` is among the section's ``backend`` values."""
    hints = get_type_hints(type(section))
    return "backend" in hints and SIM_BACKEND in get_args(hints["backend"])


def with_overrides(
    config: Config, *, sim: bool = False, replay: str | None = None, projector_calibration: str | None = None
) -> Config:
    """``--sim``: every part on its simulated backend. ``--replay PATH``: the rear camera replays PATH, the rest simulated;
    ``--projector-calibration FILE``: the map of the replayed recordings' projector streams.

    Parts switched off in the config stay off.
    """
    if not sim and not replay:
        return config
    changes: dict[str, Any] = {}
    for field in dataclasses.fields(config):
        section = getattr(config, field.name)
        if _has_sim_backend(section) and section.backend != "off":
            changes[field.name] = dataclasses.replace(section, backend=SIM_BACKEND)
    if replay:
        rear = dataclasses.replace(config.rear_camera, backend="replay", replay_path=str(replay))
        if projector_calibration:
            rear = dataclasses.replace(rear, replay_projector_calibration=str(projector_calibration))
        changes["rear_camera"] = rear
    return dataclasses.replace(config, **changes)


def status_line(report: dict[str, Any]) -> str:
    """One short line for the log and systemd's STATUS: overall state and each service's rate or trouble."""
    parts = []
    for name, entry in report.get("services", {}).items():
        if not entry.get("healthy", False):
            parts.append(f"{name} {entry.get('state')}")
        elif entry.get("state") == "simulated" and isinstance(entry.get("fps"), (int, float)):
            parts.append(f"{name} {entry['fps']:.1f} fps (simulated)")
        elif entry.get("state") == "simulated":
            parts.append(f"{name} simulated")
        elif isinstance(entry.get("fps"), (int, float)):
            parts.append(f"{name} {entry['fps']:.1f} fps")
    return f"{report.get('status', '?')}: " + (", ".join(parts) if parts else "no services")


async def run_daemon(
    config: Config,
    *,
    stop: asyncio.Event | None = None,
    hub: Hub | None = None,
    notifier: Notifier | None = None,
    builders: tuple[tuple[str, ServiceBuilder], ...] = SERVICES,
    on_started: Any = None,
    on_pi: bool | None = None,
) -> Supervisor:
    """Run every service until ``stop`` is set, then shut down within the configured budget.

    The flight loop starts first (:data:`~feelium.daemon.assembly.STARTS_FIRST`); the other parts are built
    in a worker thread meanwhile, so their imports, scenes and maps never hold the event loop, which every
    control cycle passes through, and each starts once all are built. ``on_pi`` says whether this is the blimp
    (``auto`` = hardware) or not (``auto`` = sim); ``None`` asks the device tree.
    """
    hub = hub if hub is not None else Hub()
    stop = stop if stop is not None else asyncio.Event()
    notifier = notifier if notifier is not None else Notifier()
    config = resolve_auto(config, on_raspberry_pi() if on_pi is None else on_pi)
    first = tuple(b for b in builders if b[0] in STARTS_FIRST)
    rest = tuple(b for b in builders if b[0] not in STARTS_FIRST)
    built = build_services(config, hub, first)  # on the loop: nothing runs yet (flight: its imports, then 0.1 ms)
    simulated = simulated_parts(config)
    loop_in_use = loop_kind(asyncio.get_running_loop())
    supervisor = Supervisor(
        built.services,
        config.daemon,
        clock=hub.clock,
        build_failures=built.failures,
        rebuilders=_rebuilders(first, built, config, hub),
        simulated=simulated,
        extra_health=lambda: {
            "bus": hub.bus.health(),
            "systemd": {"notify": notifier.enabled, "sent": notifier.sent},
            "event_loop": loop_in_use,
        },
    )
    hub.health = supervisor.report
    supervisor.start()
    try:
        others = await _built_off_the_loop(config, hub, rest, stop)
        if others is not None:
            supervisor.add(others.services, others.failures, _rebuilders(rest, others, config, hub))
            _log_started(config, supervisor, simulated)
            notifier.ready(f"starting: {', '.join(sorted(supervisor.records)) or 'none'}")
            if on_started is not None:
                on_started(hub, supervisor)
            await _watch(config, supervisor, notifier, stop, hub)
    finally:  # an exception here (a config error found while building included) must still leave the motors neutral
        log.info("shutting down")
        notifier.stopping()
        await supervisor.shutdown()
    log.info("stopped: %s", status_line(supervisor.report()))
    return supervisor


def _build_pixel_parts(config: Config, hub: Hub, builders: tuple[tuple[str, ServiceBuilder], ...]) -> Built:
    """``build_services``, OpenCV's pool sized first: before any part starts a thread that calls OpenCV, and off
    the loop (importing cv2 takes a tenth of a second or more)."""
    set_opencv_threads(config.daemon.opencv_threads)
    return build_services(config, hub, builders)


def set_opencv_threads(threads: int) -> int:
    """``[daemon] opencv_threads`` applied to OpenCV's pool (0: OpenCV's default, which a negative count restores);
    the pool's size now."""
    import cv2  # here, not at the module's top: the flight loop starts before anything loads OpenCV

    cv2.setNumThreads(threads if threads > 0 else -1)
    return int(cv2.getNumThreads())


async def _built_off_the_loop(
    config: Config, hub: Hub, builders: tuple[tuple[str, ServiceBuilder], ...], stop: asyncio.Event
) -> Built | None:
    """``build_services`` in a worker thread, while the loop flies; ``None`` when ``stop`` comes first (the build
    cannot be interrupted: it finishes in its thread and what it built is dropped unstarted)."""
    if not builders:
        return Built()
    building = asyncio.ensure_future(asyncio.to_thread(_build_pixel_parts, config, hub, builders))
    stopped = asyncio.ensure_future(stop.wait())
    try:
        await asyncio.wait((building, stopped), return_when=asyncio.FIRST_COMPLETED)
    finally:
        stopped.cancel()
    if building.done():
        return building.result()  # a ConfigError is raised here, after which the daemon stops, motors neutral
    building.add_done_callback(lambda f: f.cancelled() or f.exception())  # retrieved: no "never retrieved" warning
    return None


def _rebuilders(
    builders: tuple[tuple[str, ServiceBuilder], ...], built: Built, config: Config, hub: Hub
) -> dict[str, Callable[[], Service | None]]:
    """How to retry each part of ``builders`` that failed to build."""
    return {part: _builder_for(build, config, hub) for part, build in builders if part in built.failures}


def _log_started(config: Config, supervisor: Supervisor, simulated: dict[str, str]) -> None:
    """One line naming every part, then one per part saying which backend (or simulator) it runs on."""
    log.info("feelium running: %s", ", ".join(sorted(supervisor.records)) or "none")
    backends = backend_names(config)
    for part in sorted(set(supervisor.records) | set(supervisor.build_failures)):
        if part in simulated:
            log.info("%s: simulated (%s)", part, simulated[part])
        elif part in backends:
            log.info("%s: %s backend", part, backends[part])


def _builder_for(build: ServiceBuilder, config: Config, hub: Hub) -> Callable[[], Service | None]:
    """A part's build, ready for the supervisor to retry."""
    return lambda: build(config, hub)


async def _watch(config: Config, supervisor: Supervisor, notifier: Notifier, stop: asyncio.Event, hub: Hub) -> None:
    """Until ``stop``: feed the watchdog while the flight loop lives, follow health, send the status line."""
    tick = min(config.daemon.status_interval_s, notifier.watchdog_interval or 1.0, 1.0)
    next_status = hub.clock() + config.daemon.status_interval_s
    trimmer = FreeMemoryReturner(config.daemon.malloc_trim_interval_s)
    fed = True
    while not stop.is_set():
        try:
            await asyncio.wait_for(stop.wait(), tick)
        except asyncio.TimeoutError:
            pass
        now = hub.clock()
        trimmer.maybe(now)
        report = supervisor.report()  # every tick: state changes reach the log within a tick
        if notifier.watchdog_interval is not None:
            alive = supervisor.vital_alive(now, config.daemon.flight_heartbeat_s)
            if alive:
                notifier.watchdog()
                if not fed:
                    log.info("flight loop alive again: feeding the systemd watchdog")
            elif fed:
                log.error("flight loop stalled: not feeding the systemd watchdog")
            fed = alive
        if now >= next_status:
            line = status_line(report)
            log.info("%s", line)
            log.debug("health: %s", json.dumps(report, default=str, separators=(",", ":")))
            notifier.status(line)
            next_status = now + config.daemon.status_interval_s


def _install_signals(loop: asyncio.AbstractEventLoop, stop: asyncio.Event) -> None:
    """Each stop signal ends the daemon the same orderly way, motors neutral first."""

    def on_signal(sig: signal.Signals) -> None:
        if not stop.is_set():
            log.info("%s received: motors to neutral, stopping", sig.name)
        stop.set()

    for sig in STOP_SIGNALS:
        loop.add_signal_handler(sig, on_signal, sig)


def background_nice_here(setting: int, on_pi: bool) -> int:
    """``[daemon] background_nice`` resolved: ``-1`` (auto) is the Pi's value on a Pi and 0 elsewhere, where a
    laptop's other programs would otherwise starve the pixel threads of a daemon run for development or tests."""
    if setting >= 0:
        return setting
    return PI_BACKGROUND_NICE if on_pi else 0


def run_process(config: Config) -> int:
    """The whole process lifetime; exits within ``shutdown_budget_s`` (+ a little) of SIGTERM/SIGINT."""
    applied = tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)  # before any thread starts
    log.debug("malloc tuning: %s", applied or "glibc defaults")
    loop, kind = new_event_loop(config.daemon.event_loop)
    log.info("event loop: %s", kind)
    set_background_nice(background_nice_here(config.daemon.background_nice, on_raspberry_pi()))  # before the bulk-work threads start
    log.debug("pixel threads run %d nice steps below the flight loop", background_nice())
    executor = ThreadPoolExecutor(max_workers=WORKER_THREADS, thread_name_prefix="feelium-worker", initializer=lower_current_thread)
    loop.set_default_executor(executor)
    stop = asyncio.Event()
    notifier = Notifier()
    signalled_at: list[float] = []

    async def main() -> Supervisor:
        _install_signals(loop, stop)
        watcher = asyncio.create_task(stop.wait())
        watcher.add_done_callback(lambda _: signalled_at.append(time.monotonic()))
        try:
            return await run_daemon(config, stop=stop, notifier=notifier)
        finally:
            watcher.cancel()  # a start that fails (e.g. a config error) must not leave it pending on a closed loop

    try:
        supervisor = loop.run_until_complete(main())
    except ConfigError:
        raise  # a wrong setting found while building: the CLI reports it in one line (flight was stopped, neutral)
    except Exception:
        log.critical("the daemon failed; the motors were set neutral on the way out", exc_info=True)
        return 1
    finally:
        executor.shutdown(wait=False, cancel_futures=True)
        loop.run_until_complete(loop.shutdown_asyncgens())
        loop.close()
        notifier.close()
    failed = [n for n, r in supervisor.records.items() if r.state == "failed"]
    code = 1 if failed else 0
    start = signalled_at[0] if signalled_at else time.monotonic()
    _leave_in_time(code, start + config.daemon.shutdown_budget_s + 0.3)
    return code


def _leave_in_time(code: int, deadline: float) -> None:
    """Wait for worker threads until ``deadline``; a thread stuck in a device read must not hold the exit up."""
    for thread in threading.enumerate():
        if thread is threading.main_thread() or thread.daemon:
            continue
        thread.join(max(0.0, deadline - time.monotonic()))
    stuck = [t.name for t in threading.enumerate() if t is not threading.main_thread() and not t.daemon and t.is_alive()]
    if stuck:
        log.warning("exiting with threads still busy: %s", ", ".join(stuck))
        logging.shutdown()
        sys.stdout.flush()
        os._exit(code)
