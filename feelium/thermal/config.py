"""The ``[thermal]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import section, setting
from feelium.thermal.registers import REFRESH_RATES_HZ


@dataclass(frozen=True)
class PresenceConfig:
    """Presence detector: warm clusters against a slowly adapting ambient baseline."""

    enter_rise_c: float = setting(1.2, "A pixel is warm when this far above its baseline (degC).", min=0.2, max=20.0)
    leave_rise_c: float = setting(
        0.8, "While someone is present a pixel stays warm down to this rise (degC; hysteresis).", min=0.1, max=20.0
    )
    min_pixels: int = setting(3, "Smallest connected warm cluster that counts as a body (pixels).", min=1, max=768)
    enter_frames: int = setting(2, "Consecutive frames with a body before 'approach' is announced.", min=1, max=100)
    leave_frames: int = setting(4, "Consecutive frames without one before 'leave' is announced.", min=1, max=200)
    baseline_tau_s: float = setting(
        30.0, "Time constant of the ambient baseline where no body is (s).", min=1.0, max=3600.0
    )
    update_period_s: float = setting(
        1.0, "While present, an 'update' event this often (s); 0 disables updates.", min=0.0, max=60.0
    )
    fov_deg: tuple[float, ...] = setting(
        (55.0, 35.0), "Horizontal and vertical field of view of the lens (MLX90640-D55: 55 x 35 degrees)."
    )

    def __post_init__(self) -> None:
        if self.leave_rise_c > self.enter_rise_c:
            raise ValueError("leave_rise_c must not exceed enter_rise_c")
        if len(self.fov_deg) != 2 or not all(0.0 < f < 180.0 for f in self.fov_deg):
            raise ValueError("fov_deg must be two angles between 0 and 180 degrees")


@dataclass(frozen=True)
class ThermalConfig:
    """MLX90640 thermal camera and the presence detector."""

    backend: Literal["auto", "smbus2", "sim", "off"] = setting(
        "auto", "Where frames come from; auto is the sensor on /dev/i2c-<i2c_bus> on a Raspberry Pi (missing: failed) and the simulated sensor elsewhere."
    )
    i2c_bus: int = setting(1, "Linux I2C bus number (/dev/i2c-N) the sensor is on.", min=0, max=255)
    i2c_address: int = setting(0x33, "7-bit I2C address of the sensor (factory default 0x33 = 51).", min=0x08, max=0x77)
    max_read_words: int = setting(
        512, "Longest single I2C read in words; longer reads are split (the Pi's i2c-dev caps a message).", min=16, max=4096
    )
    attempts: int = setting(3, "Tries per I2C transaction before the error is counted and reported.", min=1, max=10)
    refresh_hz: float = setting(
        8.0, "Sub-page rate written to the control register; a full frame takes two sub-pages.", min=0.5, max=64.0
    )
    resolution_bits: int = setting(18, "ADC resolution written to the control register.", min=16, max=19)
    mode: Literal["chess", "interleaved"] = setting("chess", "Reading pattern (the device is calibrated in chess).")
    emissivity: float = setting(0.98, "Emissivity of what is looked at (skin is about 0.98).", min=0.1, max=1.0)
    reflected_offset_c: float = setting(
        -8.0, "Reflected temperature as an offset from the sensor's own Ta (Melexis: Ta - 8).", min=-50.0, max=50.0
    )
    retry_backoff_s: float = setting(
        0.5, "Wait after a failed sub-page read, doubling up to 8x while failures continue (s).", min=0.01, max=10.0
    )
    presence: PresenceConfig = section(PresenceConfig)

    def __post_init__(self) -> None:
        if self.refresh_hz not in REFRESH_RATES_HZ:
            raise ValueError(f"refresh_hz must be one of {REFRESH_RATES_HZ}, got {self.refresh_hz}")
