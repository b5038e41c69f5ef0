"""The MLX90640's register map and the bit fields the driver touches (datasheet section 11).

Addresses are 16-bit and every register is a 16-bit big-endian word.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

I2C_ADDRESS = 0x33

EEPROM_START = 0x2400
EEPROM_WORDS = 832  # 0x2400..0x273F
EEPROM_END = EEPROM_START + EEPROM_WORDS - 1

RAM_START = 0x0400
RAM_WORDS = 832  # 768 pixels (row-major 24x32) then 64 auxiliary words from 0x0700
RAM_END = RAM_START + RAM_WORDS - 1
PIXELS = 768
ROWS, COLS = 24, 32

STATUS = 0x8000
CONTROL = 0x800D
I2C_CONFIG = 0x800F

# Status register 0x8000
STATUS_SUBPAGE_MASK = 0x0007  # last measured sub-page (only bit 0 is used: 0 or 1)
STATUS_NEW_DATA = 0x0008  # set by the device when a sub-page is in RAM; cleared by writing 0
STATUS_OVERWRITE_ENABLED = 0x0010
STATUS_CLEAR = STATUS_OVERWRITE_ENABLED | 0x0020  # new-data cleared, overwrite kept on

# Control register 0x800D
CONTROL_SUBPAGES_ENABLED = 0x0001
CONTROL_REFRESH_SHIFT = 7
CONTROL_REFRESH_MASK = 0x0380
CONTROL_RESOLUTION_SHIFT = 10
CONTROL_RESOLUTION_MASK = 0x0C00
CONTROL_CHESS = 0x1000

# Offsets inside the 832 RAM words (datasheet RAM map, 0x0700 onwards)
AUX = 768
TA_VBE = AUX + 0  # 0x0700
CP_SUBPAGE0 = AUX + 8  # 0x0708
GAIN = AUX + 10  # 0x070A
TA_PTAT = AUX + 32  # 0x0720
CP_SUBPAGE1 = AUX + 40  # 0x0728
VDD_PIX = AUX + 42  # 0x072A
# Auxiliary words the device fills every sub-page (the others hold 0x7FFF by design)
AUX_USED = (0, *range(8, 19), *range(20, 23), *range(24, 33), *range(40, 51), *range(52, 55), *range(56, 64))

# Layout of one recorded raw frame (recording format: RAM, then status, then control)
RAW_FRAME_WORDS = RAM_WORDS + 2
RAW_STATUS = RAM_WORDS
RAW_CONTROL = RAM_WORDS + 1

INVALID_WORD = 0x7FFF

REFRESH_RATES_HZ: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0)
RESOLUTION_BITS: tuple[int, ...] = (16, 17, 18, 19)

Mode = Literal["chess", "interleaved"]


@dataclass(frozen=True)
class ControlSettings:
    """What the control register says about how the device measures."""

    refresh_hz: float
    resolution_bits: int
    mode: Mode

    @classmethod
    def from_word(cls, word: int) -> "ControlSettings":
        refresh = REFRESH_RATES_HZ[(word & CONTROL_REFRESH_MASK) >> CONTROL_REFRESH_SHIFT]
        resolution = RESOLUTION_BITS[(word & CONTROL_RESOLUTION_MASK) >> CONTROL_RESOLUTION_SHIFT]
        return cls(refresh, resolution, "chess" if word & CONTROL_CHESS else "interleaved")

    def apply(self, word: int) -> int:
        """``word`` with these fields set and every other bit kept (read-modify-write)."""
        if self.refresh_hz not in REFRESH_RATES_HZ:
            raise ValueError(f"refresh rate {self.refresh_hz} Hz is not one of {REFRESH_RATES_HZ}")
        if self.resolution_bits not in RESOLUTION_BITS:
            raise ValueError(f"ADC resolution {self.resolution_bits} bits is not one of {RESOLUTION_BITS}")
        word &= ~(CONTROL_REFRESH_MASK | CONTROL_RESOLUTION_MASK | CONTROL_CHESS) & 0xFFFF
        word |= REFRESH_RATES_HZ.index(self.refresh_hz) << CONTROL_REFRESH_SHIFT
        word |= RESOLUTION_BITS.index(self.resolution_bits) << CONTROL_RESOLUTION_SHIFT
        if self.mode == "chess":
            word |= CONTROL_CHESS
        return word | CONTROL_SUBPAGES_ENABLED


def is_eeprom_address(address: int, words: int = 1) -> bool:
    """Whether any of ``words`` words from ``address`` falls in the EEPROM (never written)."""
    return address <= EEPROM_END and address + words - 1 >= EEPROM_START
