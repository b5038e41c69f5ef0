"""The ``[thermal]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class ThermalConfig:
    """MLX90640 thermal camera and the presence detector."""

    backend: Literal["auto", "smbus2", "emulator", "off"] = setting(
        "auto", "Where frames come from; auto uses the emulator when no I2C bus answers."
    )
