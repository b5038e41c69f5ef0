"""The ``[projector]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class ProjectorConfig:
    """Inner projector output and what it renders."""

    backend: Literal["auto", "fbdev", "window", "null"] = setting(
        "auto", "Display output; auto uses the framebuffer on the blimp and null elsewhere."
    )
