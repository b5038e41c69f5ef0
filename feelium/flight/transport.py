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


def open_serial(port: str, baudrate: int, timeout_s: float) -> ByteLink:
    """Open a device path or pyserial URL; raises ``serial.SerialException`` naming the port."""
    import serial

    return serial.serial_for_url(port, baudrate=baudrate, timeout=timeout_s, write_timeout=timeout_s)
