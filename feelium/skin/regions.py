"""Envelope regions on the skin canvas: head, cheeks, palm zone, whole skin.

Positions are ``(u, v)`` in 0..1 across the camera's sensitive patch, the
same coordinates the touch events carry and the renderer's skin canvas uses,
so a region means the same spot for the sensor, the engine and the projector.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

SKIN = "skin"
REGION_ORDER = ("cheek_left", "cheek_right", "head", "palm_zone")  # small regions win where they overlap


@dataclass(frozen=True)
class Ellipse:
    cu: float
    cv: float
    ru: float
    rv: float

    def contains(self, u: float, v: float) -> bool:
        return ((u - self.cu) / self.ru) ** 2 + ((v - self.cv) / self.rv) ** 2 <= 1.0


@dataclass(frozen=True)
class Regions:
    """Named ellipses; anything else on the patch is ``skin``, off the patch ``None``."""

    areas: tuple[tuple[str, Ellipse], ...]

    @classmethod
    def from_config(cls, config: Any) -> "Regions":
        """From ``[interactions]``: a ``[cu, cv, ru, rv]`` list per name of :data:`REGION_ORDER`."""
        areas = []
        for name in REGION_ORDER:
            values = getattr(config, name)
            if len(values) != 4 or values[2] <= 0 or values[3] <= 0:
                raise ValueError(f"interactions.{name} must be [cu, cv, ru, rv] with positive radii, got {list(values)}")
            areas.append((name, Ellipse(*values)))
        return cls(tuple(areas))

    def region_at(self, u: float, v: float) -> str | None:
        """The region at skin position ``(u, v)``."""
        if not (0.0 <= u <= 1.0 and 0.0 <= v <= 1.0):
            return None
        for name, ellipse in self.areas:
            if ellipse.contains(u, v):
                return name
        return SKIN

    def centre(self, name: str) -> tuple[float, float]:
        for area_name, ellipse in self.areas:
            if area_name == name:
                return ellipse.cu, ellipse.cv
        if name == SKIN:
            return 0.5, 0.5
        raise KeyError(f"unknown region {name!r}")
