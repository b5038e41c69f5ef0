"""The ``[touch]`` config section: every parameter of the shadow pipeline."""

from __future__ import annotations

from dataclasses import dataclass

from feelium.settings import setting


@dataclass(frozen=True)
class TouchConfig:
    """Rear-camera shadow pipeline (reference, depth, gates, fingertip, tracker)."""

    width: int = setting(640, "Working resolution width in pixels; frames are resized to it.", min=32, max=4096)
    height: int = setting(480, "Working resolution height in pixels.", min=24, max=4096)
