"""The MJPEG in-flight limit: unacknowledged bytes are read from the kernel, a reader that takes nothing is stalled."""

from __future__ import annotations

import asyncio
import socket
import sys

import pytest

from feelium.http.video import unacked_bytes, wait_until_acknowledged

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="SIOCOUTQ is Linux's")


def _pair(rcvbuf: int) -> tuple[socket.socket, socket.socket]:
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(1)
        receiver = socket.socket()
        receiver.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)  # before connect: a small window
        receiver.connect(listener.getsockname())
        sender, _ = listener.accept()
    sender.setblocking(False)
    return sender, receiver


async def test_a_reader_that_takes_nothing_is_stalled_and_one_that_reads_is_not() -> None:
    sender, receiver = _pair(4096)
    try:
        sent = 0
        try:
            while sent < 400_000:
                sent += sender.send(b"x" * 16384)
        except BlockingIOError:
            pass  # the send buffer is full: the receiver's window is closed
        queued = unacked_bytes(sender)
        assert queued is not None and queued > 16384
        assert await wait_until_acknowledged(sender, 16384, timeout=0.2) is False

        async def drain() -> None:
            receiver.setblocking(False)
            got = 0
            while got < sent:
                try:
                    got += len(receiver.recv(65536))
                except BlockingIOError:
                    await asyncio.sleep(0.002)

        reader = asyncio.create_task(drain())
        assert await wait_until_acknowledged(sender, 16384, timeout=2.0) is True
        assert (unacked_bytes(sender) or 0) <= 16384
        await asyncio.wait_for(reader, 5)
    finally:
        sender.close()
        receiver.close()


def test_unknown_socket_means_no_limit() -> None:
    assert unacked_bytes(None) is None
    assert asyncio.run(wait_until_acknowledged(None, 0, timeout=0.01)) is True
