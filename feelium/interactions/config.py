"""The ``[interactions]`` config section."""

from __future__ import annotations

from dataclasses import dataclass

from feelium.settings import setting


@dataclass(frozen=True)
class InteractionsConfig:
    """Envelope regions and the rules of the six exchanges."""

    enabled: bool = setting(True, "Run the interaction engine.")
