"""The thermal camera's hardware seam: 16-bit-addressed word reads and writes over I2C.

:class:`I2CTransport` is all the driver needs. :class:`SMBus2Transport`
implements it on anything with smbus2's ``i2c_rdwr`` (a real ``smbus2.SMBus``
on the Pi, or the simulated sensor's bus in tests and in sim), so the same
byte-level code runs in both. One read is one write-then-read transaction
(repeated start, no stop in between, as the MLX90640 needs to keep its
address pointer); long reads are split into several such transactions because
the Pi's ``i2c-dev`` ioctl refuses messages beyond a few KiB. Each
transaction is retried a bounded number of times (a NACK on a shared bus is
routine) and what still fails raises ``OSError``. The EEPROM is read-only
here: a write to 0x2400..0x273F raises before touching the bus.
"""

from __future__ import annotations

import os
from typing import Any, Protocol

import numpy as np
from smbus2 import i2c_msg

from feelium.thermal import registers as reg


I2C_HINT = (
    "enable I2C and load i2c-dev (sudo raspi-config nonint do_i2c 0, or dtparam=i2c_arm=on in "
    "/boot/firmware/config.txt and i2c-dev in /etc/modules-load.d/), then reboot (docs/deploy.md)"
)


class I2CTransport(Protocol):
    """Word access to one MLX90640."""

    def read_words(self, address: int, count: int) -> np.ndarray:
        """``count`` 16-bit words from ``address`` as uint16; OSError when the bus fails."""
        ...

    def write_word(self, address: int, value: int) -> None:
        """Write one 16-bit word; OSError when the bus fails."""
        ...

    def close(self) -> None: ...


class RdwrBus(Protocol):
    """What :class:`SMBus2Transport` needs from a bus: smbus2's combined transaction."""

    def i2c_rdwr(self, *messages: Any) -> None: ...


class SMBus2Transport:
    """:class:`I2CTransport` over an smbus2-style bus: big-endian words, split reads, no EEPROM writes."""

    def __init__(
        self, bus: RdwrBus, device: int = reg.I2C_ADDRESS, max_read_words: int = 512, attempts: int = 3
    ) -> None:
        if not 1 <= max_read_words <= 4096:
            raise ValueError(f"max_read_words must be 1..4096, got {max_read_words}")
        if attempts < 1:
            raise ValueError(f"attempts must be at least 1, got {attempts}")
        self.bus = bus
        self.device = device
        self.max_read_words = max_read_words
        self.attempts = attempts
        self.transactions = 0
        self.io_errors = 0  # failed transactions, each retry counted
        self.retries = 0

    @classmethod
    def open(
        cls, bus_number: int, device: int = reg.I2C_ADDRESS, max_read_words: int = 512, attempts: int = 3
    ) -> "SMBus2Transport":
        """Open ``/dev/i2c-<bus_number>``; OSError if it does not exist, saying how to make it exist (the
        usual cause on a fresh Pi, and what health and ``feelium thermal read`` then show)."""
        from smbus2 import SMBus

        node = f"/dev/i2c-{bus_number}"
        if not os.path.exists(node):
            raise FileNotFoundError(f"{node} is missing: {I2C_HINT}")

        return cls(SMBus(bus_number), device, max_read_words, attempts)

    def _rdwr(self, *messages: Any) -> None:
        for attempt in range(self.attempts):
            try:
                self.bus.i2c_rdwr(*messages)
                self.transactions += 1
                return
            except OSError:
                self.io_errors += 1
                if attempt == self.attempts - 1:
                    raise
                self.retries += 1

    def read_words(self, address: int, count: int) -> np.ndarray:
        if not 0 <= address <= 0xFFFF or count < 1 or address + count - 1 > 0xFFFF:
            raise ValueError(f"cannot read {count} words from 0x{address:04X}")
        chunks = []
        for start in range(0, count, self.max_read_words):
            n = min(self.max_read_words, count - start)
            at = address + start
            write = i2c_msg.write(self.device, [at >> 8, at & 0xFF])
            read = i2c_msg.read(self.device, 2 * n)
            self._rdwr(write, read)
            chunks.append(np.frombuffer(bytes(read), dtype=">u2"))
        return np.concatenate(chunks).astype(np.uint16)

    def write_word(self, address: int, value: int) -> None:
        if reg.is_eeprom_address(address):
            raise PermissionError(f"refusing to write 0x{address:04X}: the EEPROM (0x2400..0x273F) is never written")
        if not 0 <= value <= 0xFFFF:
            raise ValueError(f"0x{value:X} is not a 16-bit word")
        self._rdwr(i2c_msg.write(self.device, [address >> 8, address & 0xFF, value >> 8, value & 0xFF]))

    def close(self) -> None:
        close = getattr(self.bus, "close", None)
        if close is not None:
            close()


__all__ = ["I2CTransport", "RdwrBus", "SMBus2Transport"]
