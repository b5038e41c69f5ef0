"""The ``[audio]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class AudioConfig:
    """Speech playback and capture on the blimp."""

    backend: Literal["auto", "alsa", "fake", "off"] = setting(
        "auto", "Audio device; auto uses ALSA when a sound card is found, else the fake."
    )
