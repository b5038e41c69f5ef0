"""The daemon in-process: a replayed recording's touches reach the bus; crashes are contained; systemd is told."""

from __future__ import annotations

import asyncio
import dataclasses
import importlib.util
import socket
import time

import pytest

from feelium.daemon.config import Config
from feelium.daemon.assembly import build_touch
from feelium.daemon.runner import run_daemon
from feelium.daemon.sdnotify import Notifier
from feelium.events import TouchEvent
from feelium.hub import Hub

from .fakes import CrashingService, HeartbeatService
from .synthetic import PRESS_OFF, PRESS_ON, PRESS_XY, write_press_recording

REAR_ONLY = (("touch", build_touch),)


def _replay_config(path, *, realtime=False, loop=False) -> Config:
    base = Config()
    return dataclasses.replace(
        base,
        rear_camera=dataclasses.replace(
            base.rear_camera, backend="replay", replay_path=str(path), replay_realtime=realtime, replay_loop=loop
        ),
        daemon=dataclasses.replace(base.daemon, restart_initial_s=0.01, restart_max_s=0.05, status_interval_s=0.2),
    )


async def _run_until(config, condition, *, hub=None, builders=REAR_ONLY, notifier=None, timeout=20.0):
    hub = hub if hub is not None else Hub()
    stop = asyncio.Event()
    holder = {}

    async def watch():
        deadline = time.monotonic() + timeout
        try:
            while "supervisor" not in holder or not condition(hub, holder["supervisor"]):
                assert time.monotonic() < deadline, "daemon never reached the condition"
                await asyncio.sleep(0.01)
        finally:
            stop.set()  # a condition never met fails the test (below) instead of running the daemon forever

    watcher = asyncio.create_task(watch())
    supervisor = await run_daemon(
        config,
        stop=stop,
        hub=hub,
        builders=builders,
        notifier=notifier or Notifier({}),
        on_pi=False,
        on_started=lambda h, s: holder.setdefault("supervisor", s),
    )
    await watcher
    return hub, supervisor


@pytest.mark.slow
async def test_touches_of_a_replayed_recording_reach_the_bus(tmp_path):
    recording = write_press_recording(tmp_path / "press")
    hub = Hub()
    sub = hub.bus.subscribe([TouchEvent])
    _, supervisor = await _run_until(
        _replay_config(recording), lambda h, s: s.records["touch"].state == "finished", hub=hub
    )
    events = sub.drain()
    phases = [e.phase for e in events]
    assert phases[0] == "down" and phases[-1] == "up" and phases.count("down") == 1
    down, up = events[0], events[-1]
    assert PRESS_ON <= down.t <= PRESS_ON + 0.3
    assert PRESS_OFF <= up.t <= PRESS_OFF + 0.3
    assert abs(down.x - PRESS_XY[0]) < 4 and abs(down.y - PRESS_XY[1]) < 4
    report = hub.health()
    assert report["services"]["touch"]["frames"] == int(3.5 * 15)
    assert report["services"]["touch"]["dropped_frames"] == 0  # as-fast-as-possible replay loses nothing
    assert report["services"]["touch"]["backend"] == "replay"
    if importlib.util.find_spec("feelium.touch.overlay") is not None:
        assert hub.rear_video.published > 0  # the debug view with the overlay
        assert report["services"]["touch"]["overlay_errors"] == 0
    assert report["status"] == "stopped"


@pytest.mark.slow
async def test_a_crashing_service_is_restarted_while_the_touch_pipeline_keeps_working(tmp_path, monkeypatch):
    recording = write_press_recording(tmp_path / "press", seconds=1.0)
    crashy = CrashingService(3, name="crashy")
    frames_at_first_crash = {}

    def condition(hub, supervisor):
        record = supervisor.records["crashy"]
        if record.crashes >= 1 and "n" not in frames_at_first_crash:
            frames_at_first_crash["n"] = supervisor.records["touch"].service.frames
        return crashy.runs >= 4 and crashy.ticks > 0 and supervisor.records["touch"].service.frames > frames_at_first_crash.get("n", 1e9) + 5

    hub, supervisor = await _run_until(
        _replay_config(recording, realtime=True, loop=True),
        condition,
        builders=(*REAR_ONLY, ("crashy", lambda config, hub: crashy)),
    )
    assert supervisor.records["crashy"].crashes == 3
    assert supervisor.records["touch"].crashes == 0


@pytest.mark.slow
async def test_ready_status_and_watchdog_reach_systemd_while_frames_flow(tmp_path):
    recording = write_press_recording(tmp_path / "press", seconds=1.0)
    path = str(tmp_path / "notify")
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    listener.bind(path)
    listener.setblocking(False)
    notifier = Notifier({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "200000"})
    messages: list[bytes] = []

    def condition(hub, supervisor):
        while True:
            try:
                messages.append(listener.recv(4096))
            except BlockingIOError:
                break
        return b"WATCHDOG=1" in messages and any(m.startswith(b"STATUS=ok") for m in messages)

    await _run_until(_replay_config(recording, realtime=True, loop=True), condition, notifier=notifier)
    listener.close()
    assert messages[0].startswith(b"READY=1\nSTATUS=starting: touch")


async def test_the_watchdog_is_fed_only_while_the_vital_loop_beats(monkeypatch, caplog):
    """A stalled vital loop stops the WATCHDOG=1 pings (systemd then restarts us); a fresh heartbeat resumes them."""
    base = Config()
    config = dataclasses.replace(base, daemon=dataclasses.replace(base.daemon, status_interval_s=60.0, flight_heartbeat_s=0.15))
    hub = Hub()
    camera = HeartbeatService(hub.clock, name="camera")
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    listener.bind("\0feelium-test-watchdog-%d" % id(camera))
    listener.setblocking(False)
    notifier = Notifier({"NOTIFY_SOCKET": "@" + listener.getsockname()[1:].decode(), "WATCHDOG_USEC": "100000"})
    pings: list[tuple[str, float]] = []  # (phase, time) of each WATCHDOG=1
    phase = {"name": "alive", "since": time.monotonic()}

    def drain():
        while True:
            try:
                message = listener.recv(4096)
            except BlockingIOError:
                return
            if b"WATCHDOG=1" in message:
                pings.append((phase["name"], time.monotonic()))

    def condition(hub, supervisor):
        drain()
        elapsed = time.monotonic() - phase["since"]
        if phase["name"] == "alive" and len(pings) >= 3:
            camera.frozen = True
            phase.update(name="frozen", since=time.monotonic(), frozen_at=time.monotonic())
        elif phase["name"] == "frozen" and elapsed > 0.6:
            camera.frozen = False
            phase.update(name="resumed", since=time.monotonic())
        return phase["name"] == "resumed" and any(p == "resumed" for p, _ in pings)

    with caplog.at_level("ERROR", logger="feelium.daemon.runner"):
        await _run_until(config, condition, hub=hub, builders=(("camera", lambda config, hub: camera),), notifier=notifier, timeout=10)
    listener.close()
    frozen = [t for p, t in pings if p == "frozen"]
    phase_frozen_at = phase["frozen_at"]
    # at most the pings within flight_heartbeat_s (+ one tick) of the freeze; none in the rest of the frozen phase
    assert len(frozen) <= 4 and all(t - phase_frozen_at < 0.3 for t in frozen)
    assert caplog.text.count("flight loop stalled") == 1


@pytest.mark.slow
async def test_a_press_on_the_sim_scene_becomes_a_touch_on_the_bus():
    """The partner page's path: hub.rear_scene.press/release with hub.clock() times -> sim camera -> pipeline -> bus."""
    base = Config()
    config = dataclasses.replace(
        base,
        rear_camera=dataclasses.replace(base.rear_camera, backend="sim"),
        sim=dataclasses.replace(base.sim, autoplay=False),
    )
    hub = Hub()
    sub = hub.bus.subscribe([TouchEvent])
    plan = {}

    def condition(hub, supervisor):
        scene = hub.rear_scene
        now = hub.clock()
        if "pressed" not in plan and supervisor.records["touch"].service.frames >= 20:  # the reference has settled
            x, y, w, h = scene.roi
            plan["xy"] = (x + 0.4 * w, y + 0.6 * h)
            scene.press(*plan["xy"], now)
            plan["pressed"] = now
        elif "pressed" in plan and "released" not in plan and now - plan["pressed"] > 1.2:
            scene.release(now)
            plan["released"] = now
        elif "released" in plan and now - plan["released"] > 1.0:
            return True
        return False

    await _run_until(config, condition, hub=hub, timeout=30.0)
    events = sub.drain()
    downs = [e for e in events if e.phase == "down"]
    ups = [e for e in events if e.phase == "up"]
    assert len(downs) == 1 and len(ups) == 1, [e.to_json() for e in events]
    assert abs(downs[0].x - plan["xy"][0]) < 12 and abs(downs[0].y - plan["xy"][1]) < 12
    assert plan["pressed"] <= downs[0].t <= plan["pressed"] + 1.0  # events are on the daemon's clock (GET /clock)
    assert hub.health()["services"]["touch"]["backend"] == "sim"
