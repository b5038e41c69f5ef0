"""The ``[daemon]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class DaemonConfig:
    """Process-wide settings: logging and supervision."""

    log_level: Literal["debug", "info", "warning", "error"] = setting("info", "Log level of the journald lines.")
