"""The ``[rear_camera]`` and ``[front_camera]`` config sections."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class RearCameraConfig:
    """The rear (touch) camera inside the envelope."""

    backend: Literal["auto", "picamera2", "replay", "sim"] = setting(
        "auto", "Frame source; auto uses picamera2 when a camera is found, else sim."
    )
    replay_path: str = setting("", "Recording directory for the replay backend.")


@dataclass(frozen=True)
class FrontCameraConfig:
    """The front fisheye camera: the wearer's eyes."""

    backend: Literal["auto", "picamera2", "v4l2", "replay", "sim"] = setting(
        "auto", "Frame source; auto uses picamera2 or v4l2 when found, else sim."
    )
