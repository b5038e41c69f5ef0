"""`feelium run` as a real process: it starts, and SIGTERM/SIGINT stop it cleanly within 2 s; config errors name the key."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .synthetic import write_press_recording


CHECKOUT = str(Path(__file__).resolve().parents[2])  # this checkout's feelium, not whichever one is installed


def _start(args, tmp_path, extra_env=None):
    env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=CHECKOUT, **(extra_env or {}))
    env.pop("NOTIFY_SOCKET", None)
    return subprocess.Popen(
        [sys.executable, "-m", "feelium", "run", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
        cwd=tmp_path,
        text=True,
    )


def _wait_for_line(proc, fragment, timeout=30.0):
    seen = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.2)
        if ready:
            line = proc.stdout.readline()
            if not line:
                break
            seen.append(line)
            if fragment in line:
                return seen
    proc.kill()
    raise AssertionError(f"no line with {fragment!r}; got:\n{''.join(seen)}")


@pytest.mark.slow
@pytest.mark.parametrize("event_loop", ["uvloop", "asyncio"])
def test_sigint_stops_the_daemon_within_two_seconds(tmp_path, event_loop):
    if event_loop == "uvloop":
        pytest.importorskip("uvloop")
    recording = write_press_recording(tmp_path / "press", seconds=1.0)
    config = tmp_path / "feelium.toml"
    config.write_text(f'[http]\nport = 0\n[daemon]\nstatus_interval_s = 0.5\nevent_loop = "{event_loop}"\n')
    proc = _start(["--config", str(config), "--replay", str(recording)], tmp_path)
    try:
        _wait_for_line(proc, f"event loop: {event_loop}")
        _wait_for_line(proc, "feelium running")
        _wait_for_line(proc, "touch 1")  # a status line with the touch pipeline at 1x fps: frames flow
        sent = time.monotonic()
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=10)
        elapsed = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, rest
    assert elapsed < 2.0, f"took {elapsed:.2f} s to stop\n{rest}"
    assert "shutting down" in rest and "Traceback" not in rest


@pytest.mark.slow
def test_under_systemd_verbose_journald_lines_and_sigterm_within_two_seconds(tmp_path):
    """`<N>` priority prefixes, no timestamps; `-v` gives debug lines though the config says warning; SIGTERM < 2 s."""
    recording = write_press_recording(tmp_path / "press", seconds=1.0)
    config = tmp_path / "feelium.toml"
    config.write_text('[http]\nport = 0\n[daemon]\nlog_level = "warning"\nstatus_interval_s = 0.5\n')
    proc = _start(["--config", str(config), "--replay", str(recording), "-v"], tmp_path, {"INVOCATION_ID": "test"})
    try:
        seen = _wait_for_line(proc, "<6>feelium.daemon.runner: feelium running: ")
        seen += _wait_for_line(proc, "touch 1")  # frames flow
        seen += _wait_for_line(proc, "<7>feelium.daemon.runner: health: ")
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        rest, _ = proc.communicate(timeout=10)
        elapsed = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, rest
    assert elapsed < 2.0, f"took {elapsed:.2f} s to stop\n{rest}"
    lines = [line for line in "".join(seen).splitlines() + rest.splitlines() if line.strip()]
    assert any(line.startswith("<7>feelium.daemon.assembly: touch: touch") for line in lines)
    assert any(line.startswith("<6>feelium.daemon.runner: shutting down") for line in lines)
    assert all(re.match(r"<[0-7]>[\w.]+: ", line) for line in lines), lines  # every line is a journald line
    assert not any(re.search(r"\d\d:\d\d:\d\d", line[:20]) for line in lines)  # journald adds the time


@pytest.mark.slow
def test_a_config_error_names_the_key_and_exits_1(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[rear_camera]\nbackend = "webcam"\n')
    proc = subprocess.run(
        [sys.executable, "-m", "feelium", "run", "--config", str(bad)], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 1
    assert "rear_camera.backend" in proc.stderr and "bad.toml" in proc.stderr



def _threads_nice(pid: int) -> dict[str, set[int]]:
    """Each thread name's nice values, from /proc (field 19 of a task's stat, after the parenthesised name);
    the main thread (the event loop's, task id = pid) as ``"main"``."""
    found: dict[str, set[int]] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            stat = (task / "stat").read_text()
        except FileNotFoundError:
            continue  # a thread that ended meanwhile
        name = "main" if task.name == str(pid) else re.sub(r"_\d*$", "", stat[stat.index("(") + 1 : stat.rindex(")")])
        found.setdefault(name, set()).add(int(stat[stat.rindex(")") + 2 :].split()[16]))
    return found


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads thread priorities from /proc (Linux)")
def test_pixel_threads_run_nicer_than_the_flight_loop_and_its_serial_thread(tmp_path):
    recording = write_press_recording(tmp_path / "press", seconds=1.0)
    config = tmp_path / "feelium.toml"
    config.write_text("[http]\nport = 0\n[daemon]\nstatus_interval_s = 0.5\nbackground_nice = 6\n")
    proc = _start(["--config", str(config), "--replay", str(recording)], tmp_path)
    try:
        _wait_for_line(proc, "feelium running")
        _wait_for_line(proc, "touch 1")  # frames flow: the camera and pipeline threads exist
        base = os.getpriority(os.PRIO_PROCESS, proc.pid)
        threads = _threads_nice(proc.pid)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=10)
    bulk = min(19, base + 6)
    assert threads["main"] == {base}, threads  # the event loop: flight control, stop, every reply
    assert threads["flight-serial"] == {base}, threads
    assert threads["touch-pipeline"] == {bulk}, threads
    assert threads["rear-camera"] == {bulk}, threads
    assert threads["feelium-worker"] == {bulk}, threads
