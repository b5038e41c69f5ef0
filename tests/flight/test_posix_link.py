"""The real port's fast path (:class:`PosixLink`): the same bytes as pyserial's reads, in fewer system calls.

A pty stands in for the UART, the emulated board (``board_server.serve``) answers on its other end in a
thread, and the client's own system calls are counted by wrapping ``os.read``, ``os.write``, ``select``
and the ``in_waiting`` ioctl for the calling thread only (the board's thread makes its own).
"""

from __future__ import annotations

import fcntl
import os
import select
import threading
import time
import tty
from collections import Counter
from collections.abc import Iterator

import pytest

from feelium.daemon.config import Config
from feelium.flight import messages as m
from feelium.flight.client import MspClient
from feelium.flight.service import SimOpener
from feelium.flight.transport import PosixLink, open_serial
from feelium.lab.daemon.board_server import serve

TIMEOUT_S = 0.05


@pytest.fixture
def pty_port() -> Iterator[tuple[int, str]]:
    master, slave = os.openpty()
    tty.setraw(slave)
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)


def test_a_device_path_opens_as_the_fast_link_and_reads_as_pyserial_does(pty_port: tuple[int, str]) -> None:
    master, path = pty_port
    link = open_serial(path, 115200, TIMEOUT_S)
    try:
        assert isinstance(link, PosixLink)
        assert link.read_some() == b""  # nothing came within the timeout
        os.write(master, bytes(range(200)))
        deadline = time.monotonic() + 2.0
        while link.in_waiting < 200 and time.monotonic() < deadline:
            time.sleep(0.001)
        assert link.read(3) == bytes(range(3))  # what was asked for, no more
        assert link.read_some() == bytes(range(3, 200))  # one call takes all that is there
        os.write(master, b"ab")
        assert link.read(5) == b"ab"  # short after the timeout, as pyserial's read
        assert link.write(b"xyz") == 3 and os.read(master, 16) == b"xyz"
    finally:
        link.close()


class _Syscalls:
    """Counts this thread's port I/O calls by kind while installed."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.counts: Counter[str] = Counter()
        self.thread = threading.get_ident()
        for module, name in ((os, "read"), (os, "write"), (select, "select"), (fcntl, "ioctl")):
            monkeypatch.setattr(module, name, self._counted(name, getattr(module, name)))

    def _counted(self, name: str, real):  # type: ignore[no-untyped-def]
        def call(*args, **kwargs):  # type: ignore[no-untyped-def]
            if threading.get_ident() == self.thread:
                self.counts[name] += 1
            return real(*args, **kwargs)

        return call


def test_a_control_tick_is_a_handful_of_system_calls(monkeypatch: pytest.MonkeyPatch) -> None:
    """Poll (with the last tick's motor ack waiting) and command: pyserial alone took ~13 calls a tick."""
    master, slave = os.openpty()
    tty.setraw(slave)
    config = Config()
    link = open_serial(os.ttyname(slave), config.flight.baudrate, TIMEOUT_S)
    os.close(slave)  # the link holds the only slave end: closing it ends the board's thread (EIO) before the master goes
    board = threading.Thread(target=serve, args=(master, SimOpener(config.flight, 1, time.monotonic).open()))
    board.start()
    client = MspClient(link, timeout_s=TIMEOUT_S)
    try:
        ticks = 20
        client.poll()
        client.send_motors(m.NEUTRAL_MOTORS_US)
        time.sleep(0.02)
        calls = _Syscalls(monkeypatch)
        answered = 0
        for _ in range(ticks):
            answered += client.poll().heading_deg is not None
            client.send_motors(m.NEUTRAL_MOTORS_US)
            time.sleep(0.02)  # the tick's period: the ack arrives before the next poll
        monkeypatch.undo()
        assert answered == ticks and client.timeouts == 0
        per_tick = sum(calls.counts.values()) / ticks
        assert calls.counts["write"] == 2 * ticks  # the burst and the motor command, one write each
        assert per_tick <= 8, dict(calls.counts)
    finally:
        link.close()
        board.join(5.0)
        os.close(master)
    assert not board.is_alive()
