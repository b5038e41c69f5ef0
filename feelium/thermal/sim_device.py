"""The simulated MLX90640 (sim): lives in memory and answers the same I2C transactions as the sensor.

It holds an EEPROM image (the vendor's example device unless given one) and,
given a scene of object temperatures, writes RAM frames by running the
datasheet's equations backwards, one sub-page at a time at the refresh rate
its control register says, raising the new-data bit as the device does. The
driver talks to it through :meth:`SimMlx90640.bus`, an object with
smbus2's ``i2c_rdwr``, so tests and the simulator exercise the real
transport, driver and decoder byte for byte.

Faults it can inject, for the driver's error paths: NACKs (``OSError``
EREMOTEIO, as the kernel reports them), 0x7FFF words in a sub-page, a
data-ready bit that will not clear, and a slow bus (each transaction takes
time, so a sub-page can land in the middle of a read and tear it).

Time comes from the ``clock``/``sleep`` pair it is given: a
:class:`VirtualClock` in tests, the real clock in the simulator.
"""

from __future__ import annotations

import ctypes
import errno
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from feelium.thermal import registers as reg
from feelium.thermal.calibration import Calibration, extract_calibration
from feelium.thermal.decoder import CONVERSION_PATTERN, IL_PATTERN, KELVIN, ambient_temperature, subpage_mask, supply_voltage
from feelium.thermal.vendor_eeprom import vendor_eeprom

POWER_ON_CONTROL = 0x1901  # 2 Hz, 18-bit, chess: the device's factory default

Scene = Callable[[float], np.ndarray]


class VirtualClock:
    """A clock that only moves when slept on: deterministic time for tests."""

    def __init__(self, start: float = 0.0) -> None:
        self.t = float(start)

    def __call__(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += max(0.0, float(seconds))


@dataclass
class Faults:
    """What goes wrong, and how often (probabilities per transaction or per sub-page)."""

    nack_rate: float = 0.0  # each transaction fails with EREMOTEIO
    nack_next: int = 0  # the next N transactions fail (deterministic)
    invalid_word_rate: float = 0.0  # a sub-page's pixels carry a 0x7FFF word
    stale_ready: bool = False  # writes to the status register do not clear the new-data bit
    seconds_per_word: float = 0.0  # bus time per transferred word (slow bus)


def _signed_word(value: np.ndarray | float) -> np.ndarray:
    """Round to int16 and store as the uint16 bit pattern (0x7FFF is the device's no-data marker)."""
    v = np.clip(np.rint(np.asarray(value, dtype=np.float64)), -0x8000, 0x7FFE).astype(np.int64)
    return (v & 0xFFFF).astype(np.uint16)


class SimMlx90640:
    """The sensor, simulated. ``scene(t)`` gives the (24, 32) degC object temperatures at time ``t``."""

    def __init__(
        self,
        scene: Scene | np.ndarray | None = None,
        *,
        eeprom: np.ndarray | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
        rng: np.random.Generator | None = None,
        ta_c: float = 30.0,
        vdd: float = 3.3,
        adc_noise_counts: float = 0.0,
        faults: Faults | None = None,
        device: int = reg.I2C_ADDRESS,
    ) -> None:
        self.eeprom = (vendor_eeprom() if eeprom is None else np.asarray(eeprom)).astype(np.uint16).copy()
        self.cal: Calibration = extract_calibration(self.eeprom)
        self.clock = clock
        self.sleep = sleep
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.ta_c = float(ta_c)
        self.vdd = float(vdd)
        self.adc_noise_counts = float(adc_noise_counts)
        self.faults = faults if faults is not None else Faults()
        self.device = device
        self.set_scene(scene if scene is not None else np.full((reg.ROWS, reg.COLS), 22.0))
        self.ram = np.full(reg.RAM_WORDS, reg.INVALID_WORD, dtype=np.uint16)
        self.control = POWER_ON_CONTROL
        self.status = reg.STATUS_OVERWRITE_ENABLED
        self.i2c_config = 0x0000
        self._t0 = self.clock()
        self._measured = 0  # sub-pages completed since the period started
        self.subpages_written = 0
        self.transactions = 0
        self.nacks = 0
        self.eeprom_write_attempts = 0

    # -- scene -------------------------------------------------------------------------------------

    def set_scene(self, scene: Scene | np.ndarray) -> None:
        """A fixed image or a function of time giving object temperatures in degC."""
        if callable(scene):
            self._scene: Scene = scene
            return
        image = np.asarray(scene, dtype=np.float64)
        if image.shape != (reg.ROWS, reg.COLS):
            raise ValueError(f"scene must be (24, 32) degC, got shape {image.shape}")
        self._scene = lambda t, image=image.copy(): image

    @property
    def period_s(self) -> float:
        """Time between sub-pages at the refresh rate the control register holds."""
        return 1.0 / reg.ControlSettings.from_word(self.control).refresh_hz

    # -- the model run backwards ------------------------------------------------------------------

    def raw_subpage(self, subpage: int, celsius: np.ndarray) -> np.ndarray:
        """The 832 RAM words the device would write for ``subpage`` seeing ``celsius`` (the other half kept)."""
        cal = self.cal
        settings = reg.ControlSettings.from_word(self.control)
        ram = self.ram.copy()
        aux = np.full(64, reg.INVALID_WORD, dtype=np.uint16)
        aux[list(reg.AUX_USED)] = 0x0001
        ram[reg.AUX :] = aux

        frame = np.zeros(reg.RAW_FRAME_WORDS, dtype=np.int64)
        frame[reg.RAW_CONTROL] = self.control
        resolution_ram = (self.control & reg.CONTROL_RESOLUTION_MASK) >> reg.CONTROL_RESOLUTION_SHIFT
        correction = 2.0**cal.resolutionEE / 2.0**resolution_ram
        ram[reg.VDD_PIX] = _signed_word(((self.vdd - 3.3) * cal.kVdd + cal.vdd25) / correction)
        frame[: reg.RAM_WORDS] = ram
        vdd = supply_voltage(cal, frame)

        ptat = 1700.0 + float(self.rng.normal(0.0, 1.0)) * self.adc_noise_counts
        target = ((self.ta_c - 25.0) * cal.KtPTAT + cal.vPTAT25) * (1.0 + cal.KvPTAT * (vdd - 3.3))
        ram[reg.TA_PTAT] = _signed_word(ptat)
        ram[reg.TA_VBE] = _signed_word(ptat * 2.0**18 / target - ptat * cal.alphaPTAT)
        gain_word = round(cal.gainEE * 0.987)
        ram[reg.GAIN] = _signed_word(gain_word)
        frame[: reg.RAM_WORDS] = ram
        ta = ambient_temperature(cal, frame, vdd)
        gain = cal.gainEE / gain_word

        dta, dvdd = ta - 25.0, vdd - 3.3
        chess = settings.mode == "chess"
        compensated = (0x80 if chess else 0) == cal.calibrationModeEE
        cp_scale = (1.0 + cal.cpKta * dta) * (1.0 + cal.cpKv * dvdd)
        cp1_offset = cal.cpOffset[1] if compensated else cal.cpOffset[1] + cal.ilChessC[0]
        ram[reg.CP_SUBPAGE0] = _signed_word(cal.cpOffset[0] * cp_scale / gain)
        ram[reg.CP_SUBPAGE1] = _signed_word(cp1_offset * cp_scale / gain)
        frame[: reg.RAM_WORDS] = ram
        ir_cp = (float(np.int16(ram[reg.CP_SUBPAGE0])) * gain - cal.cpOffset[0] * cp_scale,
                 float(np.int16(ram[reg.CP_SUBPAGE1])) * gain - cp1_offset * cp_scale)[subpage]

        idx = np.flatnonzero(subpage_mask(settings.mode, subpage))
        to = np.asarray(celsius, dtype=np.float64).reshape(-1)[idx]
        ta4 = (ta + KELVIN) ** 4
        tr4 = (ta - 8.0 + KELVIN) ** 4
        ta_tr = tr4 - (tr4 - ta4)  # emissivity 1: the scene is given as object temperatures
        ks_to, ct = np.asarray(cal.ksTo), np.asarray(cal.ct, dtype=np.float64)
        corr = np.array([1.0 / (1.0 + ks_to[0] * 40.0), 1.0, 1.0 + ks_to[2] * ct[2],
                         (1.0 + ks_to[2] * ct[2]) * (1.0 + ks_to[3] * (ct[3] - ct[2]))])
        rng_idx = np.searchsorted(ct[1:], to, side="right")
        alpha = (cal.alpha[idx] - cal.tgc * cal.cpAlpha[subpage]) * (1.0 + cal.KsTa * dta)
        ir = alpha * corr[rng_idx] * (1.0 + ks_to[rng_idx] * (to - ct[rng_idx])) * ((to + KELVIN) ** 4 - ta_tr)
        ir = ir + cal.tgc * ir_cp
        if not compensated:
            ir = ir - (cal.ilChessC[2] * (2 * IL_PATTERN[idx] - 1) - cal.ilChessC[1] * CONVERSION_PATTERN[idx])
        ir = ir + cal.offset[idx] * (1.0 + cal.kta[idx] * dta) * (1.0 + cal.kv[idx] * dvdd)
        raw = ir / gain
        if self.adc_noise_counts > 0:
            raw = raw + self.rng.normal(0.0, self.adc_noise_counts, raw.shape)
        ram[idx] = _signed_word(raw)
        if self.faults.invalid_word_rate > 0 and self.rng.random() < self.faults.invalid_word_rate:
            ram[idx[int(self.rng.integers(len(idx)))]] = reg.INVALID_WORD
        return ram

    # -- time --------------------------------------------------------------------------------------

    def _advance(self) -> None:
        """Write every sub-page that completed since the last transaction (at most the last two)."""
        now = self.clock()
        due = int((now - self._t0) / self.period_s)
        if due <= self._measured:
            return
        first = max(self._measured, due - 2)
        for n in range(first, due):
            subpage = n % 2
            t = self._t0 + (n + 1) * self.period_s
            self.ram = self.raw_subpage(subpage, self._scene(t))
            self.status = (self.status & ~reg.STATUS_SUBPAGE_MASK) | subpage | reg.STATUS_NEW_DATA
            self.subpages_written += 1
        self._measured = due

    def _restart_period(self) -> None:
        self._t0 = self.clock()
        self._measured = 0

    # -- I2C -------------------------------------------------------------------------------------

    def read(self, address: int, count: int) -> np.ndarray:
        """The words the device returns for a read of ``count`` words from ``address`` (0 where nothing is mapped).

        Copied by ranges, not word by word: the bench charges this simulation to the thermal service, and on
        the blimp the same read is the I2C controller's work, not Python's."""
        out = np.zeros(count, dtype=np.uint16)
        end = address + count
        for first, memory in ((reg.EEPROM_START, self.eeprom), (reg.RAM_START, self.ram)):
            lo, hi = max(address, first), min(end, first + len(memory))
            if lo < hi:
                out[lo - address : hi - address] = memory[lo - first : hi - first]
        for register, value in ((reg.STATUS, self.status), (reg.CONTROL, self.control), (reg.I2C_CONFIG, self.i2c_config)):
            if address <= register < end:
                out[register - address] = value
        return out

    def write(self, address: int, value: int) -> None:
        if reg.is_eeprom_address(address):
            self.eeprom_write_attempts += 1  # the device needs an erase sequence; a plain write changes nothing
        elif address == reg.STATUS:
            keep_ready = self.faults.stale_ready and self.status & reg.STATUS_NEW_DATA
            self.status = (value & ~reg.STATUS_SUBPAGE_MASK & ~reg.STATUS_NEW_DATA) | (self.status & reg.STATUS_SUBPAGE_MASK)
            self.status &= 0xFFDF  # the start-measurement bit self-clears
            if keep_ready:
                self.status |= reg.STATUS_NEW_DATA
        elif address == reg.CONTROL:
            if value != self.control:
                self.control = value & 0xFFFF
                self._restart_period()
        elif address == reg.I2C_CONFIG:
            self.i2c_config = value & 0xFFFF

    def transaction(self, messages: tuple[Any, ...]) -> None:
        """One combined I2C transaction of smbus2 ``i2c_msg`` objects (write address [+ data], then read)."""
        self.transactions += 1
        if self.faults.nack_next > 0:
            self.faults.nack_next -= 1
            self._nack()
        if self.faults.nack_rate > 0 and self.rng.random() < self.faults.nack_rate:
            self._nack()
        if not messages or any(m.addr != self.device for m in messages):
            self._nack()
        self._advance()
        first = bytes(messages[0])
        if messages[0].flags & 0x0001 or len(first) < 2:
            self._nack()
        address = (first[0] << 8) | first[1]
        words = 0
        if len(messages) == 1:
            if len(first) != 4:
                self._nack()
            self.write(address, (first[2] << 8) | first[3])
            words = 1
        else:
            for msg in messages[1:]:
                if not msg.flags & 0x0001 or msg.len % 2:
                    self._nack()
                data = self.read(address, msg.len // 2).astype(">u2").tobytes()
                ctypes.memmove(msg.buf, data, len(data))
                words += msg.len // 2
                address += msg.len // 2
        if self.faults.seconds_per_word > 0:
            self.sleep(words * self.faults.seconds_per_word)

    def _nack(self) -> None:
        self.nacks += 1
        raise OSError(errno.EREMOTEIO, "Remote I/O error (simulated NACK)")

    def bus(self) -> "SimBus":
        """An smbus2-like bus with this device on it."""
        return SimBus(self)


class SimBus:
    """The subset of ``smbus2.SMBus`` the transport uses, wired to a simulated sensor."""

    def __init__(self, device: SimMlx90640) -> None:
        self.device = device
        self.closed = False

    def i2c_rdwr(self, *messages: Any) -> None:
        if self.closed:
            raise OSError(errno.EBADF, "bus closed")
        self.device.transaction(messages)

    def close(self) -> None:
        self.closed = True


__all__ = ["SimBus", "Faults", "SimMlx90640", "POWER_ON_CONTROL", "VirtualClock"]
