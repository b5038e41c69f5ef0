"""The MLX90640 driver: configure the device, read its calibration once, fetch each new sub-page.

It talks words through an :class:`~feelium.thermal.transport.I2CTransport`
(which retries each transaction a bounded number of times) and never reads a
clock: the service decides when to poll. A bus failure raises ``OSError`` to
the caller, which counts it.

A sub-page read is: status (is there new data, which sub-page), clear the
new-data bit, the 832 RAM words, status again. If the device finished
another sub-page meanwhile (the sub-page bit flipped) the read is torn: the
RAM holds halves of two measurements, so it is dropped and counted. A
sub-page whose pixel words are identical to the previous read of the same
sub-page is stale (a data-ready bit that did not clear) and is dropped too.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np

from feelium.thermal import registers as reg
from feelium.thermal.calibration import Calibration, extract_calibration
from feelium.thermal.decoder import subpage_mask
from feelium.thermal.transport import I2CTransport

@dataclass
class DriverCounters:
    """What went wrong on the bus and with frames since start (reported in health)."""

    subpages: int = 0  # sub-pages delivered
    torn: int = 0
    stale: int = 0
    not_ready: int = 0  # polls that found no new data

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


@dataclass
class Mlx90640Driver:
    """One MLX90640 behind ``transport``."""

    transport: I2CTransport
    settings: reg.ControlSettings = field(default_factory=lambda: reg.ControlSettings(8.0, 18, "chess"))
    counters: DriverCounters = field(default_factory=DriverCounters)
    eeprom: np.ndarray | None = None
    calibration: Calibration | None = None
    control: int | None = None
    _last_pixels: dict[int, np.ndarray] = field(default_factory=dict)

    def read_words(self, address: int, count: int) -> np.ndarray:
        return self.transport.read_words(address, count)

    def write_word(self, address: int, value: int) -> None:
        self.transport.write_word(address, value)

    def health(self) -> dict[str, int]:
        """The driver's counters and the transport's bus error counts."""
        out = self.counters.as_dict()
        for name in ("transactions", "io_errors", "retries"):
            if hasattr(self.transport, name):
                out[name] = int(getattr(self.transport, name))
        return out

    def start(self) -> Calibration:
        """Read and check the calibration (CalibrationError if the dump is bad) and apply the settings."""
        self.eeprom = self.read_words(reg.EEPROM_START, reg.EEPROM_WORDS)
        self.calibration = extract_calibration(self.eeprom)
        current = int(self.read_words(reg.CONTROL, 1)[0])
        wanted = self.settings.apply(current)
        if wanted != current:
            self.write_word(reg.CONTROL, wanted)
            current = int(self.read_words(reg.CONTROL, 1)[0])
            if current != wanted:
                raise OSError(f"control register reads 0x{current:04X} after writing 0x{wanted:04X}")
        self.control = current
        self._last_pixels.clear()
        return self.calibration

    def poll(self) -> np.ndarray | None:
        """The newest sub-page as 834 raw words (RAM, status, control), or ``None`` if none is ready or it was bad."""
        if self.control is None:
            raise RuntimeError("call start() before poll()")
        before = int(self.read_words(reg.STATUS, 1)[0])
        if not before & reg.STATUS_NEW_DATA:
            self.counters.not_ready += 1
            return None
        self.write_word(reg.STATUS, reg.STATUS_CLEAR)
        ram = self.read_words(reg.RAM_START, reg.RAM_WORDS)
        after = int(self.read_words(reg.STATUS, 1)[0])
        subpage = before & 1
        if after & 1 != subpage:
            self.counters.torn += 1
            return None
        mode = reg.ControlSettings.from_word(self.control).mode
        pixels = ram[: reg.PIXELS][subpage_mask(mode, subpage)]
        previous = self._last_pixels.get(subpage)
        if previous is not None and np.array_equal(previous, pixels):
            self.counters.stale += 1
            return None
        self._last_pixels[subpage] = pixels
        self.counters.subpages += 1
        return np.concatenate([ram, np.array([before, self.control], dtype=np.uint16)])

    def close(self) -> None:
        self.transport.close()


__all__ = ["DriverCounters", "Mlx90640Driver"]
