"""Every way `feelium run` ends leaves the motors neutral: a real process flying the emulated board over TCP.

SIGTERM, SIGINT, SIGHUP and SIGQUIT: the daemon's last word to the board is
neutral (1500 us on all four motors), sent after the signal. SIGKILL and
SIGABRT cannot be caught: the board's own 300 ms watchdog must set neutral.
An exception escaping the daemon's loop: neutral, then exit 1.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from feelium.flight.messages import NEUTRAL_MOTORS_US

from .board_server import BoardServer

WATCHDOG_S = 0.3


def _config(tmp_path, board: BoardServer):
    """The flight loop on the emulated board; every other part off (or simulated, for the projector that has no off)."""
    path = tmp_path / "feelium.toml"
    path.write_text(
        f'[flight]\nbackend = "serial"\nport = "{board.url}"\n'
        '[rear_camera]\nbackend = "off"\n[front_camera]\nbackend = "off"\n[thermal]\nbackend = "off"\n'
        '[audio]\nbackend = "off"\n[projector]\nbackend = "sim"\n[http]\nenabled = false\n'
    )
    return path


def _start(tmp_path, board: BoardServer) -> subprocess.Popen:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env.pop("NOTIFY_SOCKET", None)
    return subprocess.Popen(
        [sys.executable, "-m", "feelium", "run", "--config", str(_config(tmp_path, board))],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
        cwd=os.getcwd(),  # this checkout's feelium, first on sys.path
        text=True,
    )


def _flying(board: BoardServer, proc: subprocess.Popen, timeout: float = 30.0) -> None:
    """Until the daemon has commanded the board for a while with a real (non-neutral) command."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()[0]
        last = board.last_command()
        if last is not None and len(board.commands) > 25 and last[1] != NEUTRAL_MOTORS_US:
            return
        time.sleep(0.05)
    proc.kill()
    raise AssertionError(f"the daemon never flew the board:\n{proc.communicate()[0]}")


@pytest.fixture
def board():
    server = BoardServer()
    yield server
    server.close()


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT], ids=lambda s: s.name)
def test_a_stop_signal_sends_neutral_last_then_exits(tmp_path, board, sig):
    proc = _start(tmp_path, board)
    try:
        _flying(board, proc)
        sent = time.monotonic()
        proc.send_signal(sig)
        out, _ = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert board.wait_hung_up(5.0), f"the daemon left its link to the board open:\n{out}"
    arrived, motors = board.last_command()
    assert motors == NEUTRAL_MOTORS_US and arrived >= sent, out
    assert proc.returncode == 0, out
    assert f"{sig.name} received: motors to neutral, stopping" in out and "Traceback" not in out


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGABRT], ids=lambda s: s.name)
def test_an_uncatchable_end_leaves_it_to_the_board_watchdog(tmp_path, board, sig):
    proc = _start(tmp_path, board)
    try:
        _flying(board, proc)
        proc.send_signal(sig)
        proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    died = time.monotonic()
    arrived, last = board.last_command()
    assert last != NEUTRAL_MOTORS_US  # the daemon said nothing more: what follows is the board's own doing
    assert proc.returncode == -sig
    while time.monotonic() < arrived + WATCHDOG_S + 0.15:
        time.sleep(0.01)
    assert board.motors_us() == NEUTRAL_MOTORS_US
    assert board.board.watchdog_trips >= 1
    assert died - arrived < 0.5  # the last command really was the dying daemon's


CRASH_IN_THE_LOOP = """
import logging
import sys
from feelium.daemon import runner
from feelium.daemon.config import load_config
from feelium.daemon.journal import setup_logging

calls = []

def status_line(report):  # a bug that shows only once the blimp flies: the daemon's own loop raises
    flight = report.get("services", {}).get("flight", {})
    if isinstance(flight.get("fps"), (int, float)) and flight["fps"] > 0:
        calls.append(1)  # counted only once the flight loop runs, however slowly a loaded machine starts it
    if len(calls) > 3:
        raise RuntimeError("a bug in the daemon's loop")
    return "ok"

runner.status_line = status_line
setup_logging(logging.INFO)
sys.exit(runner.run_process(load_config(sys.argv[1])))
"""


@pytest.mark.slow
def test_an_unhandled_exception_sends_neutral_then_exits_1(tmp_path, board):
    config = _config(tmp_path, board)
    config.write_text(config.read_text() + "[daemon]\nstatus_interval_s = 0.5\n")
    env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=os.getcwd())
    env.pop("NOTIFY_SOCKET", None)
    done = subprocess.run(
        [sys.executable, "-c", CRASH_IN_THE_LOOP, str(config)], capture_output=True, text=True, timeout=60, env=env
    )
    out = done.stdout + done.stderr
    assert done.returncode == 1, out
    assert "the daemon failed; the motors were set neutral on the way out" in out and "a bug in the daemon's loop" in out
    assert board.wait_hung_up(5.0), out
    assert len(board.commands) > 25, out  # it flew before the bug struck
    assert board.last_command()[1] == NEUTRAL_MOTORS_US
