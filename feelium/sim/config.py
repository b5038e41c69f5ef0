"""The ``[sim]`` config section: the simulated blimp used when there is no hardware."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class SimConfig:
    """Scene simulator used by sim backends."""

    seed: int = setting(1, "Random seed of the simulated scene.", min=0)
    session: Literal["s1", "s2", "s3"] = setting(
        "s1", "Lighting, noise and projector of the live scene: one of the paper-protocol sessions."
    )
    room_light: float = setting(
        0.0,
        "The room's own light through the membrane, as a fraction of the projector's mean back-light on the sensing "
        "patch: 0 the paper's dim room, 1 a lit living room (docs/touch.md, A lit room); a lamp off to one side.",
        min=0.0,
        max=8.0,
    )
    autoplay: bool = setting(
        True, "When nobody presses for a while, the live scene pats, holds, strokes or hovers by itself."
    )
    autoplay_period_s: float = setting(8.0, "Mean time between autoplay actions, seconds.", min=1.0, max=3600.0)
    autoplay_idle_s: float = setting(
        15.0, "Autoplay waits this long after the last manual press or release, seconds.", min=0.0, max=3600.0
    )
