"""The ``[flight]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class FlightConfig:
    """Motor board link and the closed-loop controller."""

    backend: Literal["auto", "serial", "sim", "off"] = setting(
        "auto", "Motor board: a serial port, the blimp simulator, or off; auto picks sim without hardware."
    )
