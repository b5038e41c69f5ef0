"""The real serial port's write deadline survives a thread that waits for the GIL after writing."""

from __future__ import annotations

import os
import time
import tty

import pytest
import serial
from serial import serialposix

from feelium.flight.transport import WRITE_TIMEOUT_S, open_serial

REPLY_TIMEOUT_S = 0.03  # the flight config's reply_timeout_s, once also the write deadline


@pytest.fixture
def pty_port():  # type: ignore[no-untyped-def]
    master, slave = os.openpty()
    tty.setraw(slave)
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)


def _slow_after_writing(monkeypatch: pytest.MonkeyPatch, wait_s: float) -> None:
    """os.write as pyserial sees it when another thread holds the GIL for ``wait_s`` after the bytes went out."""
    real_write = os.write

    def write(fd: int, data: bytes) -> int:
        n = real_write(fd, data)
        time.sleep(wait_s)
        return n

    monkeypatch.setattr(serialposix.os, "write", write)


def test_a_write_delayed_past_the_reply_timeout_is_not_a_dead_link(pty_port, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    master, path = pty_port
    _slow_after_writing(monkeypatch, 2 * REPLY_TIMEOUT_S)
    with serial.Serial(path, 115200, timeout=REPLY_TIMEOUT_S, write_timeout=REPLY_TIMEOUT_S) as naive:
        with pytest.raises(serial.SerialTimeoutException):  # the failure: every byte was sent, yet "Write timeout"
            naive.write(b"$M<\x00\x64\x64")
    assert os.read(master, 64) == b"$M<\x00\x64\x64"

    link = open_serial(path, 115200, REPLY_TIMEOUT_S)
    try:
        assert link.write(b"$M<\x00\x65\x65") == 6
        assert os.read(master, 64) == b"$M<\x00\x65\x65"
    finally:
        link.close()


def test_a_port_that_takes_no_bytes_still_times_out(pty_port) -> None:  # type: ignore[no-untyped-def]
    master, path = pty_port
    link = open_serial(path, 115200, REPLY_TIMEOUT_S)
    started = time.monotonic()
    try:
        with pytest.raises(serial.SerialTimeoutException):
            for _ in range(100_000):  # nobody reads the master: the pty's buffer fills, then writes block
                link.write(b"x" * 1024)
    finally:
        link.close()
    assert time.monotonic() - started < 5 * WRITE_TIMEOUT_S + 2.0


def test_a_socket_links_in_waiting_counts_every_byte_that_came_not_only_whether_one_did() -> None:
    """pyserial's socket port says 0 or 1; the client's drain then took one byte of a burst and counted the rest
    stale (the session-32 review, finding 2)."""
    import socket

    from feelium.flight.transport import BufferedLink

    server = socket.create_server(("127.0.0.1", 0))
    link = open_serial(f"socket://127.0.0.1:{server.getsockname()[1]}", 115200, REPLY_TIMEOUT_S)
    conn, _ = server.accept()
    try:
        assert isinstance(link, BufferedLink)
        conn.sendall(bytes(range(150)))
        deadline = time.monotonic() + 2.0
        while link.in_waiting < 150 and time.monotonic() < deadline:
            time.sleep(0.005)
        assert link.in_waiting == 150
        assert link.read(100) == bytes(range(100))
        assert link.read_some() == bytes(range(100, 150))
        assert link.read_some() == b""  # nothing came within the timeout
        conn.sendall(b"\x01\x02")
        assert link.read(2) == b"\x01\x02"  # waits for bytes not yet there, up to the timeout
    finally:
        link.close()
        conn.close()
        server.close()


def test_the_client_flies_a_board_over_a_socket_without_stale_bytes_or_resyncs() -> None:
    """A healthy board on TCP (the project's own board server) resynchronised about nine times a second."""
    from feelium.flight.client import MspClient
    from tests.daemon.board_server import BoardServer

    board = BoardServer()
    link = open_serial(board.url, 115200, REPLY_TIMEOUT_S)
    try:
        client = MspClient(link, timeout_s=REPLY_TIMEOUT_S)
        for _ in range(100):
            client.send_motors((1500, 1500, 1500, 1500))
            telemetry = client.poll()
            time.sleep(0.005)
        assert telemetry.range_m is not None
        assert client.resyncs == 0 and client.stale_bytes == 0 and client.stalls == 0
    finally:
        link.close()
        board.close()


@pytest.mark.parametrize("port, says", [("foo://bar", "protocol 'foo' not known"), ("rfc2217://localhost:1", "not supported")])
def test_a_port_url_no_link_can_serve_is_refused_as_a_serial_error_naming_it(port: str, says: str) -> None:
    """An unknown scheme raised ValueError (a traceback from calibrate flight; the service's reopen loop expects a
    serial error); RFC 2217 raised NotImplementedError for the write deadline (the session-32 review)."""
    with pytest.raises(serial.SerialException, match=says) as raised:
        open_serial(port, 115200, REPLY_TIMEOUT_S)
    assert port in str(raised.value)
