"""A body leaning in against the blimp (a hug): a large soft shadow around a large contact.

Sizes are adult ones (stated, not fitted): the chest of a person hugging a
64 cm blimp presses a patch of about 200 x 160 mm (semi-axes ``contact_mm``;
about 250 cm^2, more than a whole hand can cover), while the rest of the
torso (shoulders 400 mm wide, 500 mm tall: semi-axes ``torso_mm``) curves away
from the sphere (rings at growing heights, :data:`_CURVE`) and casts a soft
shadow ``torso_gap_mm`` above the skin. The
clothing pressed on the membrane is given the same extra contact loss as skin
(the simulator has no separate figure for fabric). ``height_mm`` lifts the
whole body (the approach); the contact exists only at 0.
"""

from __future__ import annotations

from dataclasses import dataclass

from feelium.sim.shadow import Ellipse, Part

# The chest curves away from the envelope around the pressed patch: (size factor of the patch, gap mm). Two
# convex surfaces of radii ~0.32 m (the blimp) and ~0.3 m (a chest across) pressed over a patch of half-width a
# part by about (r^2 - a^2) / (2 x 0.155 m) at r from its centre: 7-10 mm at 1.15 a, 17-26 mm at 1.35 a
# (a = 80-100 mm), the torso's 40 mm beyond.
_CURVE = ((1.0, 0.0), (1.15, 8.0), (1.35, 20.0))


@dataclass(frozen=True)
class Lean:
    """A torso at (x, y) camera px, ``height_mm`` above the membrane (0: pressed)."""

    x: float
    y: float
    height_mm: float
    contact_mm: tuple[float, float] = (100.0, 80.0)
    torso_mm: tuple[float, float] = (200.0, 250.0)
    torso_gap_mm: float = 40.0
    angle_deg: float = 0.0
    press: float = 1.0  # contact footprint size factor (ramps as the body settles against the skin)

    def parts(self, px_per_mm: float) -> tuple[list[Part], list[Ellipse]]:
        """Occluding parts and, when pressed, the contact footprint."""
        h = max(self.height_mm, 0.0)
        tx, ty = self.torso_mm
        cx, cy = self.contact_mm
        parts: list[Part] = [
            Ellipse(self.x, self.y, tx * px_per_mm, ty * px_per_mm, self.angle_deg, h + self.torso_gap_mm)
        ]
        for grow, gap in _CURVE:
            parts.append(Ellipse(self.x, self.y, cx * grow * px_per_mm, cy * grow * px_per_mm, self.angle_deg, h + gap))
        contacts = []
        if h <= 0.0 and self.press > 0.0:
            f = min(self.press, 1.0)
            contacts.append(Ellipse(self.x, self.y, cx * px_per_mm * f, cy * px_per_mm * f, self.angle_deg, 0.0))
        return parts, contacts

