"""The serial seam: what the MSP client needs from a byte link, and how to open a real one.

pyserial's ``serial_for_url`` already understands device paths
(``/dev/ttyAMA0``) and URLs (``socket://host:port``, ``loop://``), so the
real backend is one call; the simulated board implements the same four
members, which is all the client touches.
"""

from __future__ import annotations

from typing import Protocol


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


def open_serial(port: str, baudrate: int, timeout_s: float) -> ByteLink:
    """Open a device path or pyserial URL; raises ``serial.SerialException`` naming the port.

    ``timeout_s`` bounds a read; a write gets :data:`WRITE_TIMEOUT_S` (or ``timeout_s`` if longer).
    """
    import serial

    return serial.serial_for_url(port, baudrate=baudrate, timeout=timeout_s, write_timeout=max(timeout_s, WRITE_TIMEOUT_S))
