"""Fault injection on the real daemon in sim: what health says, what the log says (once per change), what systemd gets.

Each test runs ``run_daemon`` in-process with the real services and backends,
breaks one part (missing at start, failing mid-run, a camera that stalls, a
flight loop that hangs) and checks
that only that part suffers, that the journal says so once, and whether the
systemd watchdog keeps being fed. What the motors get when the process ends
is in ``test_signals.py``.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import socket
import threading
import time
from collections.abc import Callable
from typing import Any

import pytest

from feelium.cameras.sim import SimRearCamera
from feelium.daemon.config import Config
from feelium.daemon.runner import run_daemon
from feelium.daemon.sdnotify import Notifier
from feelium.daemon.supervisor import Supervisor
from feelium.hub import Hub


def _config(**backends: str) -> Config:
    """Fast restarts; the named parts on the given backends, every other part off (the projector has no off: sim)."""
    base = Config()
    sections = {
        "rear_camera": "off", "front_camera": "off", "thermal": "off", "audio": "off", "projector": "sim", "flight": "off",
        **backends,
    }
    changes: dict[str, Any] = {name: dataclasses.replace(getattr(base, name), backend=value) for name, value in sections.items()}
    changes["daemon"] = dataclasses.replace(
        base.daemon, restart_initial_s=0.05, restart_max_s=0.2, status_interval_s=60.0, flight_heartbeat_s=0.3
    )
    changes["http"] = dataclasses.replace(base.http, enabled=False)
    changes["sim"] = dataclasses.replace(base.sim, autoplay=False)
    return dataclasses.replace(base, **changes)


class Watchdog:
    """A systemd notify socket, read by its own thread, that records when each ``WATCHDOG=1`` arrived."""

    def __init__(self, interval_s: float = 0.05) -> None:
        self.socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.socket.bind("\0feelium-test-faults-%d" % id(self))
        self.socket.settimeout(0.05)
        usec = str(int(2 * interval_s * 1e6))
        self.notifier = Notifier({"NOTIFY_SOCKET": "@" + self.socket.getsockname()[1:].decode(), "WATCHDOG_USEC": usec})
        self.pings: list[float] = []
        self._closed = threading.Event()
        self._reader = threading.Thread(target=self._read, name="test-systemd", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        while not self._closed.is_set():
            try:
                message = self.socket.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if b"WATCHDOG=1" in message:
                self.pings.append(time.monotonic())

    def pings_since(self, t: float) -> int:
        return sum(1 for p in list(self.pings) if p >= t)

    def close(self) -> None:
        self._closed.set()
        self._reader.join(1.0)
        self.socket.close()


async def _run(
    config: Config,
    script: Callable[[Hub, Supervisor], Any],
    *,
    on_pi: bool = False,
    notifier: Notifier | None = None,
    timeout: float = 20.0,
) -> tuple[Hub, Supervisor]:
    """Run the daemon while the async ``script(hub, supervisor)`` injects faults and checks; then stop it."""
    hub = Hub()
    stop = asyncio.Event()
    holder: dict[str, Supervisor] = {}
    result: dict[str, Any] = {}

    async def drive() -> None:
        while "supervisor" not in holder:
            await asyncio.sleep(0.01)
        try:
            await asyncio.wait_for(script(hub, holder["supervisor"]), timeout)
        except BaseException as exc:  # re-raised after the daemon has stopped
            result["error"] = exc
        finally:
            stop.set()

    driver = asyncio.create_task(drive())
    supervisor = await run_daemon(
        config,
        stop=stop,
        hub=hub,
        notifier=notifier or Notifier({}),
        on_pi=on_pi,
        on_started=lambda h, s: holder.setdefault("supervisor", s),
    )
    await driver
    if "error" in result:
        raise result["error"]
    return hub, supervisor


async def _until(condition: Callable[[], bool], timeout: float = 10.0, what: str = "condition") -> float:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"{what} not reached within {timeout} s"
        await asyncio.sleep(0.02)
    return time.monotonic()


def _state(hub: Hub, part: str) -> str | None:
    return hub.health()["services"].get(part, {}).get("state")


def _transitions(caplog: pytest.LogCaptureFixture, part: str, state: str) -> list[logging.LogRecord]:
    return [r for r in caplog.records if r.name == "feelium.daemon.health" and r.getMessage().startswith(f"{part}: {state}")]


async def test_on_a_pi_missing_hardware_fails_loudly_never_silently_simulated(caplog, tmp_path, monkeypatch):
    """No camera, no I2C sensor, no motor board, no framebuffer, no alsa-utils: each part failed with its reason,
    one error line each; the thermal and audio reasons say what to enable or install."""
    monkeypatch.setenv("PATH", str(tmp_path))  # no aplay/arecord: alsa-utils not installed
    base = _config(rear_camera="auto", thermal="auto", flight="auto", projector="auto", audio="auto")
    config = dataclasses.replace(
        base,
        thermal=dataclasses.replace(base.thermal, i2c_bus=250, retry_backoff_s=0.05),
        flight=dataclasses.replace(base.flight, port="/dev/feelium-test-no-board"),
        projector=dataclasses.replace(base.projector, fb_device="/dev/feelium-test-no-fb"),
    )
    parts = ("touch", "thermal", "flight", "projector", "audio")
    watchdog = Watchdog()

    async def script(hub: Hub, supervisor: Supervisor) -> None:
        await _until(lambda: all(_state(hub, p) == "failed" for p in parts), what="every part failed")
        failed_at = time.monotonic()
        await asyncio.sleep(1.5)  # several retries of each: the journal must not repeat itself
        report = hub.health()
        services = report["services"]
        assert report["status"] == "failed"  # flight failed among them: the blimp is grounded
        assert all(services[p]["state"] == "failed" and not services[p]["simulated"] for p in parts), services
        assert "picamera2" in services["touch"]["reason"].lower() or "camera" in services["touch"]["reason"].lower()
        assert "/dev/feelium-test-no-board" in services["flight"]["reason"]
        assert "/dev/i2c-250 is missing" in services["thermal"]["reason"]
        assert "raspi-config nonint do_i2c 0" in services["thermal"]["reason"] and "i2c-dev" in services["thermal"]["reason"]
        assert "aplay is not installed: sudo apt install alsa-utils" in services["audio"]["reason"]
        assert "\n" not in services["thermal"]["reason"] + services["audio"]["reason"]
        assert services["projector"]["reason"].startswith("cannot build") and "retrying in" in services["projector"]["reason"]
        assert services["touch"]["crashes"] >= 3 and services["touch"]["since_s"] >= 1.5
        # the flight loop still runs (its link is down): the watchdog is fed though nothing works
        assert watchdog.pings_since(failed_at + 0.5) >= 5

    with caplog.at_level(logging.INFO):
        _, supervisor = await _run(config, script, on_pi=True, notifier=watchdog.notifier)
    watchdog.close()
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    for part in parts:
        assert len([r for r in errors if r.getMessage().startswith(f"{part}: failed")]) == 1, [r.getMessage() for r in errors]
    assert len(errors) == len(parts), [r.getMessage() for r in errors]
    assert not any("simulated" in r.getMessage() for r in caplog.records)


async def test_off_a_pi_auto_is_the_simulator_and_health_and_log_say_simulated(caplog):
    config = _config(rear_camera="auto", thermal="auto", flight="auto", projector="auto")
    # The shipped heartbeat, as in the thermal test below: this test counts "simulated" transitions, and in CI at load
    # 10 the flight thread went 0.7 s without a cycle while thermal and touch started, a true stall by 0.3 s that
    # health rightly reported (degraded, then simulated again: two transitions), not what this test is about.
    config = dataclasses.replace(
        config, daemon=dataclasses.replace(config.daemon, flight_heartbeat_s=Config().daemon.flight_heartbeat_s)
    )

    async def script(hub: Hub, supervisor: Supervisor) -> None:
        await _until(lambda: all(_state(hub, p) == "simulated" for p in ("touch", "thermal", "flight", "projector")), 20.0)
        report = hub.health()
        assert report["status"] == "ok"
        assert report["services"]["flight"]["reason"] == "flight on its simulator"

    with caplog.at_level(logging.INFO):
        await _run(config, script, on_pi=False)
    startup = [r.getMessage() for r in caplog.records if r.name == "feelium.daemon.runner"]
    for part in ("touch", "thermal", "flight", "projector"):
        assert any(line.startswith(f"{part}: simulated") for line in startup), startup
        assert len(_transitions(caplog, part, "simulated")) == 1


async def test_a_part_failing_mid_run_degrades_only_that_part_and_flight_keeps_flying(caplog, monkeypatch):
    """The thermal sensor stops answering mid-run: thermal failed (one error line), flight and touch unaffected."""
    config = _config(rear_camera="sim", thermal="sim", flight="sim")
    # The shipped heartbeat (1 s), not _config's 0.3 s: this test is about thermal, and at start-up on a loaded
    # 2-core machine (the suite's other worker busy) the flight loop once went 0.8 s without a cycle while the
    # simulated rear camera was built: a true stall by 0.3 s, logged as an ERROR this test does not expect.
    config = dataclasses.replace(
        config,
        thermal=dataclasses.replace(config.thermal, retry_backoff_s=0.05),
        daemon=dataclasses.replace(config.daemon, flight_heartbeat_s=Config().daemon.flight_heartbeat_s),
    )
    watchdog = Watchdog()

    async def script(hub: Hub, supervisor: Supervisor) -> None:
        await _until(lambda: all(_state(hub, p) == "simulated" for p in ("touch", "thermal", "flight")), 20.0)
        thermal = supervisor.records["thermal"].service
        assert thermal.driver is not None

        def unplugged() -> None:
            raise OSError(121, "Remote I/O error")

        monkeypatch.setattr(thermal.driver, "poll", unplugged)
        broke = time.monotonic()
        cycles = supervisor.records["flight"].service.cycles
        frames = supervisor.records["touch"].service.frames
        await _until(lambda: _state(hub, "thermal") == "failed", 5.0, "thermal failed")
        await asyncio.sleep(1.0)
        services = hub.health()["services"]
        assert "Remote I/O error" in services["thermal"]["reason"] and services["thermal"]["last_error"]
        assert services["flight"]["state"] == "simulated" and services["touch"]["state"] == "simulated"
        assert supervisor.records["flight"].service.cycles > cycles + 20  # 50 Hz loop, a second later
        assert supervisor.records["touch"].service.frames > frames + 3
        assert watchdog.pings_since(broke + 0.3) >= 5
        assert hub.health()["status"] == "degraded"

    with caplog.at_level(logging.INFO):
        await _run(config, script, notifier=watchdog.notifier)
    watchdog.close()
    assert len(_transitions(caplog, "thermal", "degraded")) <= 1
    assert len(_transitions(caplog, "thermal", "failed")) == 1
    assert [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR] == [_transitions(caplog, "thermal", "failed")[0].getMessage()]


async def test_a_stalled_rear_camera_reads_zero_fps_within_two_seconds_and_is_degraded(caplog, monkeypatch):
    config = _config(rear_camera="sim", flight="sim")
    config = dataclasses.replace(config, rear_camera=dataclasses.replace(config.rear_camera, stale_after_s=1.0))
    release = threading.Event()
    stalled = threading.Event()
    read = SimRearCamera.read

    def stalling_read(self: SimRearCamera) -> Any:
        if stalled.is_set():
            release.wait(30.0)  # a driver stuck in a read: no error, no frame
            return None
        return read(self)

    monkeypatch.setattr(SimRearCamera, "read", stalling_read)

    async def script(hub: Hub, supervisor: Supervisor) -> None:
        await _until(lambda: hub.health()["services"]["touch"]["fps"] > 5.0, 20.0, "frames flowing")
        stalled.set()
        since = time.monotonic()
        zero_at = await _until(lambda: hub.health()["services"]["touch"]["fps"] == 0.0, 3.0, "0 fps")
        assert zero_at - since <= 2.0
        await _until(lambda: _state(hub, "touch") == "degraded", 3.0, "touch degraded")
        await asyncio.sleep(0.5)
        entry = hub.health()["services"]["touch"]
        assert entry["state"] == "degraded" and entry["reason"].startswith("no rear camera frame for")
        assert _state(hub, "flight") == "simulated"
        release.set()

    try:
        with caplog.at_level(logging.INFO):
            await _run(config, script)
    finally:
        release.set()
    assert len(_transitions(caplog, "touch", "degraded")) == 1


async def test_the_watchdog_is_fed_with_the_rear_camera_dead_and_stops_when_the_flight_loop_is_stuck(caplog):
    config = _config(rear_camera="picamera2", flight="sim")  # no picamera2 here: the rear camera is dead
    watchdog = Watchdog()
    released = threading.Event()

    async def script(hub: Hub, supervisor: Supervisor) -> None:
        await _until(lambda: _state(hub, "touch") == "failed" and _state(hub, "flight") == "simulated", 20.0)
        dead = time.monotonic()
        # Fed on every tick (~0.05 s) while the camera stays dead; on a loaded machine (the suite's other worker
        # on 2 cores) the loop ticks less often, so the count is waited for rather than timed (4 in 1 s seen twice
        # in full suites, never alone), and no stall may have been logged meanwhile.
        await _until(lambda: watchdog.pings_since(dead) >= 10, 5.0, "10 watchdog pings with the camera dead")
        assert not [r for r in caplog.records if "flight loop stalled" in r.getMessage()]
        flight = supervisor.records["flight"].service

        tick = flight._tick

        def stuck(*args: Any) -> Any:  # a tick that does not return: the event loop is alive, flight is not
            released.wait()
            return tick(*args)

        flight._tick = stuck
        hung = time.monotonic()
        try:
            await asyncio.sleep(1.5)
        finally:
            released.set()  # the serial thread must end, or the interpreter waits for it at exit
        late = [p for p in list(watchdog.pings) if p > hung + config.daemon.flight_heartbeat_s + 0.15]
        assert late == [], f"{len(late)} pings after the flight loop hung"

    with caplog.at_level(logging.INFO):
        await _run(config, script, notifier=watchdog.notifier)
    watchdog.close()
    stalls = [r for r in caplog.records if "flight loop stalled" in r.getMessage()]
    assert len(stalls) == 1 and stalls[0].levelno == logging.ERROR

