"""The serial seam: what the MSP client needs from a byte link, and how to open a real one.

pyserial's ``serial_for_url`` already understands device paths
(``/dev/ttyAMA0``) and URLs (``socket://host:port``, ``loop://``), so the
real backend is one call; the simulated board implements the same four
members, which is all the client touches. A device path is wrapped in
:class:`PosixLink`, which does a control tick's I/O in fewer system calls; a
URL (``socket://``, ``loop://``) in :class:`BufferedLink`, whose ``in_waiting``
counts every byte that came.
"""

from __future__ import annotations

import os
import select
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    import serial


class ByteLink(Protocol):
    """A half of a serial line: pyserial's ``Serial`` satisfies it, so does the simulated board."""

    @property
    def in_waiting(self) -> int: ...

    def write(self, data: bytes) -> int | None: ...

    def read(self, size: int = 1) -> bytes: ...

    def close(self) -> None: ...


# pyserial (3.5, serialposix) checks a write's deadline *after* os.write returns: a thread that then waits for
# the GIL longer than the deadline (the touch or projector thread holding it) gets "Write timeout" for bytes
# already sent, and the link is dropped for nothing. With the reply timeout (30 ms) as the write deadline that
# happened dozens of times in a loaded 30-minute soak. The deadline is there to catch a port that really stops
# taking bytes (a USB adapter pulled, a wedged UART); half a second does that, far above any GIL wait, and the
# board's own 300 ms watchdog has set neutral by then anyway.
WRITE_TIMEOUT_S = 0.5
READ_CHUNK = 4096  # more than a control tick's replies (~150 bytes): one read takes all that is there


def open_serial(port: str, baudrate: int, timeout_s: float) -> ByteLink:
    """Open a device path or pyserial URL; raises ``serial.SerialException`` naming the port.

    ``timeout_s`` bounds a read; a write gets :data:`WRITE_TIMEOUT_S` (or ``timeout_s`` if longer).
    """
    import serial
    from serial.serialposix import Serial as PosixSerial

    if port.lower().startswith("rfc2217://"):
        # pyserial's RFC 2217 client supports no write deadline, and each change of its timeout renegotiates the port
        # with the server (50 ms or more): no tick could keep its period
        raise serial.SerialException(f"cannot open {port}: rfc2217:// is not supported for the motor board; use "
                                     "socket:// (a raw TCP bridge) or the serial device")
    try:
        link = serial.serial_for_url(port, baudrate=baudrate, timeout=timeout_s, write_timeout=max(timeout_s, WRITE_TIMEOUT_S))
    except ValueError as exc:  # a URL pyserial does not know ("foo://"), a malformed one: the port's fault, named
        raise serial.SerialException(f"cannot open {port}: {exc}") from exc
    return PosixLink(link) if isinstance(link, PosixSerial) else BufferedLink(link)


def read_some_of(link: ByteLink) -> Callable[[], bytes]:
    """The link's "wait up to its timeout for a byte, then take all that is there" read.

    :class:`PosixLink` has one of its own (a ``select`` and a ``read``); any other link reads
    ``max(1, in_waiting)`` bytes, which is what the client always did.
    """
    read_some: Callable[[], bytes] | None = getattr(link, "read_some", None)
    return read_some if read_some is not None else lambda: link.read(max(1, link.in_waiting))


class PosixLink:
    """pyserial's POSIX port, with a control tick's reads and writes as single system calls where they can be.

    Over a tick pyserial spent ~13 system calls: each ``read`` a ``select`` before its ``read`` and a
    reply burst read as one byte, then the rest; each ``write`` a ``select`` after it (because a write
    timeout is set). Here a write is one ``write`` (pyserial's, with its deadline, only for what the port
    did not take at once), a read of bytes known to be waiting one ``read``, and :meth:`read_some` one
    ``select`` and one ``read`` for everything that came. The port's descriptor is non-blocking
    (pyserial opens it so), so none of these can hang; what they raise is an ``OSError``, as pyserial's.
    """

    def __init__(self, port: serial.Serial) -> None:
        self.port = port
        self.fd: int = port.fd
        self.timeout_s: float | None = port.timeout

    @property
    def in_waiting(self) -> int:
        return int(self.port.in_waiting)

    def write(self, data: bytes) -> int:
        try:
            sent = os.write(self.fd, data)
        except BlockingIOError:  # the output buffer is full: pyserial waits, up to its write deadline
            sent = 0
        if sent < len(data):
            self.port.write(data[sent:])
        return len(data)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes: at once if they are there, else pyserial's read waits for the rest."""
        try:
            data = os.read(self.fd, size)
        except BlockingIOError:
            data = b""
        if len(data) < size:
            data += self.port.read(size - len(data))
        return data

    def read_some(self) -> bytes:
        """Whatever comes within the read timeout, all of it that is there then; empty if nothing came."""
        ready, _, _ = select.select([self.fd], [], [], self.timeout_s)
        if not ready:
            return b""
        try:
            data = os.read(self.fd, READ_CHUNK)
        except BlockingIOError:  # taken by no one else (one thread owns the port): a spurious wake-up
            return b""
        if not data:
            from serial import SerialException

            raise SerialException("device reports readiness to read but returned no data (device disconnected?)")
        return data

    def close(self) -> None:
        self.port.close()


class BufferedLink:
    """A pyserial URL port (``socket://``, ``loop://``) with an ``in_waiting`` that counts bytes.

    pyserial's socket port answers ``in_waiting`` with 0 or 1 (whether the socket is readable), where the client
    needs the count: its drain of what waited before a burst then read one byte of the last tick's acks and
    counted the rest stale, resynchronised about nine times a second on a healthy board, and after a stall drained
    a byte a tick while nine came (the session-32 review: still resyncing 44 s later, the controller in its
    failsafe). Here every byte the port has is pulled into a buffer at once (one non-blocking read of up to
    ``READ_CHUNK``), and ``in_waiting`` is the buffer's length. One thread owns a link, as with the others.
    """

    def __init__(self, port: serial.Serial) -> None:
        self.port = port
        self._buffer = bytearray()

    def _pull(self) -> None:
        """Move everything the port holds now into the buffer, without waiting."""
        timeout, self.port.timeout = self.port.timeout, 0
        try:
            while True:
                data = self.port.read(READ_CHUNK)
                self._buffer += data
                if len(data) < READ_CHUNK:
                    return
        finally:
            self.port.timeout = timeout

    @property
    def in_waiting(self) -> int:
        self._pull()
        return len(self._buffer)

    def write(self, data: bytes) -> int | None:
        return self.port.write(data)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes: the buffer's first, then the port's read waits up to its timeout for the rest."""
        if len(self._buffer) < size:
            self._pull()
        data = bytes(self._buffer[:size])
        del self._buffer[:size]
        if len(data) < size:
            data += self.port.read(size - len(data))
        return data

    def read_some(self) -> bytes:
        """Whatever comes within the read timeout, all of it that is there then; empty if nothing came."""
        self._pull()
        if not self._buffer:
            self._buffer += self.port.read(1)  # waits up to the port's timeout
            if self._buffer:
                self._pull()
        data = bytes(self._buffer)
        self._buffer.clear()
        return data

    def close(self) -> None:
        self.port.close()
