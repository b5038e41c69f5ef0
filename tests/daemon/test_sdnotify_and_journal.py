"""sd_notify over a real datagram socket (path and abstract) and journald-style log lines."""

from __future__ import annotations

import io
import logging
import os
import socket

import pytest

from feelium.daemon.journal import effective_level, setup_logging, under_systemd
from feelium.daemon.sdnotify import Notifier, socket_address, watchdog_interval


@pytest.fixture(autouse=True)
def _restore_root_logger():
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    yield
    root.handlers[:] = handlers
    root.setLevel(level)


def _listener(address):
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(address)
    sock.settimeout(1.0)
    return sock


def test_notifies_a_socket_path(tmp_path):
    path = str(tmp_path / "notify")
    with _listener(path) as sock:
        notifier = Notifier({"NOTIFY_SOCKET": path})
        assert notifier.enabled
        assert notifier.ready("up: touch")
        assert sock.recv(4096) == b"READY=1\nSTATUS=up: touch"
        assert notifier.watchdog()
        assert sock.recv(4096) == b"WATCHDOG=1"
        notifier.stopping()
        assert sock.recv(4096) == b"STOPPING=1\nSTATUS=stopping"
        assert notifier.sent == 3
        notifier.close()


def test_notifies_an_abstract_socket():
    name = f"feelium-test-{os.getpid()}"
    with _listener("\0" + name) as sock:
        notifier = Notifier({"NOTIFY_SOCKET": "@" + name})
        assert notifier.status("hello")
        assert sock.recv(4096) == b"STATUS=hello"
        notifier.close()


def test_without_systemd_every_call_is_a_quiet_no_op():
    notifier = Notifier({})
    assert not notifier.enabled and notifier.watchdog_interval is None
    assert notifier.ready("x") is False


def test_a_vanished_socket_is_counted_not_raised(tmp_path):
    notifier = Notifier({"NOTIFY_SOCKET": str(tmp_path / "gone")})
    assert notifier.watchdog() is False
    assert notifier.errors == 1


def test_socket_address_and_watchdog_interval():
    assert socket_address("@abc") == "\0abc"
    assert socket_address("/run/systemd/notify") == "/run/systemd/notify"
    assert watchdog_interval({"WATCHDOG_USEC": "10000000"}, 42) == pytest.approx(5.0)
    assert watchdog_interval({"WATCHDOG_USEC": "10000000", "WATCHDOG_PID": "41"}, 42) is None
    assert watchdog_interval({"WATCHDOG_USEC": "10000000", "WATCHDOG_PID": "42"}, 42) == pytest.approx(5.0)
    assert watchdog_interval({"WATCHDOG_USEC": "junk"}, 42) is None
    assert watchdog_interval({}, 42) is None


def test_journal_lines_carry_priorities_and_no_timestamp():
    stream = io.StringIO()
    setup_logging(logging.DEBUG, journal=True, stream=stream)
    log = logging.getLogger("feelium.test")
    log.info("hello")
    log.error("bad")
    try:
        raise ValueError("why")
    except ValueError:
        log.exception("crashed")
    lines = stream.getvalue().splitlines()
    assert lines[0] == "<6>feelium.test: hello"
    assert lines[1] == "<3>feelium.test: bad"
    assert lines[2] == "<3>feelium.test: crashed"
    assert all(line.startswith("<3>") for line in lines[3:]) and "ValueError: why" in lines[-1]


def test_terminal_lines_carry_a_time_and_level():
    stream = io.StringIO()
    setup_logging(logging.INFO, journal=False, stream=stream)
    logging.getLogger("feelium.test").debug("hidden")
    logging.getLogger("feelium.test").warning("shown")
    text = stream.getvalue()
    assert "hidden" not in text
    assert "WARNING feelium.test: shown" in text


def test_levels_and_systemd_detection():
    assert effective_level("warning", 0) == logging.WARNING
    assert effective_level("warning", 1) == logging.DEBUG
    assert under_systemd({"INVOCATION_ID": "abc"}) and under_systemd({"JOURNAL_STREAM": "8:1"})
    assert not under_systemd({})
