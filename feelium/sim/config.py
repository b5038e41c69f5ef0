"""The ``[sim]`` config section: the simulated blimp used when there is no hardware."""

from __future__ import annotations

from dataclasses import dataclass

from feelium.settings import setting


@dataclass(frozen=True)
class SimConfig:
    """Scene simulator used by sim backends."""

    seed: int = setting(1, "Random seed of the simulated scene.", min=0)
