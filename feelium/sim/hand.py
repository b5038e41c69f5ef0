"""A hand outside the membrane as flat parts with heights, for the shadow renderer.

The hand is posed by its fingertip: where it is on the membrane (camera px),
how high it is (mm; 0 = pressed), which way the arm lies (``heading``: the
in-plane direction from fingertip towards the wrist) and how steeply the finger
rises (``pitch``). From there the index finger rises in segments to the
knuckles, the palm sits above the knuckles, the curled fingers and thumb hang
beside it and the forearm leaves the frame. A pressed fingertip (height 0) also
gets a contact patch, an ellipse of 8 to 14 px radius at 2 px/mm.

Sizes are typical adult values (index finger ~80 mm, 16 mm wide; palm ~85 x
90 mm; forearm ~60 mm wide), scaled by ``size``.

Two more poses, for several contacts and large ones (issue 17, point 4):

- ``spread_mm > 0``: the middle finger is extended too, its tip ``spread_mm``
  beside the index's (a V of two fingertips, both pressed when the hand is);
- ``flat``: the hand pressed flat, ``(x, y)`` the centre of the palm: the palm's
  pads (an ellipse of 36 x 32 mm semi-axes, 36 cm^2: the hollow of the palm does
  not touch) and the four fingers side by side (each 75 x 16 mm) and the thumb
  (50 x 18 mm) lie on the membrane, about 80 cm^2 of contact, within the 60-120
  cm^2 a flat adult hand leaves on a surface; the rest of the palm shades the
  membrane 5 mm up (the hollow); the wrist and forearm rise away.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from feelium.sim.shadow import Capsule, Ellipse, Part

# Breakpoints along the index finger, mm from the fingertip: short segments near the
# tip, where height changes matter most for the shadow's sharpness.
_FINGER_BREAKS_MM = (0.0, 7.0, 16.0, 30.0, 50.0, 80.0)
_FINGER_RADIUS_MM = 8.0


@dataclass(frozen=True)
class HandPose:
    """Where the hand is at one instant."""

    x: float  # fingertip (contact centre) in camera px
    y: float
    tip_mm: float  # fingertip height above the membrane; 0 = pressed
    heading: float = math.pi / 2  # radians, image direction from fingertip towards the wrist
    pitch_deg: float = 35.0  # how steeply the finger rises from the membrane
    press: float = 1.0  # contact patch size factor while pressed (ramps at onset and release)
    size: float = 1.0  # hand size factor
    open_hand: bool = False  # all four fingers extended (a waving or sweeping hand)
    left: bool = False  # which side the thumb is on
    spread_mm: float = 0.0  # > 0: the middle finger extended too, its tip this far beside the index's
    flat: bool = False  # the whole hand flat, (x, y) the palm's centre

    @property
    def pressed(self) -> bool:
        return self.tip_mm <= 0.0 and self.press > 0.0


def hand_parts(pose: HandPose, px_per_mm: float) -> tuple[list[Part], list[Ellipse]]:
    """The occluding parts and, when pressed, the contact patch of a posed hand."""
    if pose.flat:
        return flat_hand_parts(pose, px_per_mm)
    k = px_per_mm * pose.size
    ux, uy = math.cos(pose.heading), math.sin(pose.heading)
    side = -1.0 if pose.left else 1.0
    nx, ny = -uy * side, ux * side
    pitch = math.radians(pose.pitch_deg)
    cos_p, sin_p = math.cos(pitch), math.sin(pitch)
    h0 = max(pose.tip_mm, 0.0)

    def at(along_mm: float, across_mm: float) -> tuple[float, float]:
        return pose.x + (ux * along_mm + nx * across_mm) * k, pose.y + (uy * along_mm + ny * across_mm) * k

    parts: list[Part] = []
    fingers = [(0.0, 0.0, 1.0, 0.0)]  # (across mm, along offset mm, length factor, extra height mm)
    if pose.open_hand:
        fingers += [(17.0, -4.0, 1.1, 3.0), (34.0, 2.0, 1.05, 4.0), (50.0, 14.0, 0.85, 6.0)]
    elif pose.spread_mm > 0.0:
        fingers.append((pose.spread_mm, 0.0, 1.0, 0.0))
    for across, along0, length, extra in fingers:
        for a, b in zip(_FINGER_BREAKS_MM[:-1], _FINGER_BREAKS_MM[1:]):
            a, b = a * length, b * length
            x0, y0 = at(along0 + a * cos_p, across)
            x1, y1 = at(along0 + b * cos_p, across)
            height = h0 + extra + 0.5 * (a + b) * sin_p
            parts.append(Capsule(x0, y0, x1, y1, _FINGER_RADIUS_MM * k, height))

    base_along = _FINGER_BREAKS_MM[-1] * cos_p
    base_h = h0 + _FINGER_BREAKS_MM[-1] * sin_p
    palm_pitch = math.radians(20.0)
    palm_cx, palm_cy = at(base_along + 45.0 * math.cos(palm_pitch), 20.0)
    angle = math.degrees(pose.heading)
    parts.append(Ellipse(palm_cx, palm_cy, 48.0 * k, 44.0 * k, angle, base_h + 15.0))
    if not pose.open_hand:
        curled = ((34.0, 8.0), (48.0, 10.0)) if pose.spread_mm > 0.0 else ((18.0, 6.0), (34.0, 8.0), (48.0, 10.0))
        for across, drop in curled:  # curled fingers under the knuckles
            cx, cy = at(base_along - 6.0, across)
            parts.append(Ellipse(cx, cy, 12.0 * k, 9.0 * k, angle, max(h0 + 8.0, base_h - drop)))
    tx0, ty0 = at(base_along + 30.0, -22.0)
    tx1, ty1 = at(base_along + 2.0, -38.0)
    parts.append(Capsule(tx0, ty0, tx1, ty1, 10.0 * k, base_h + 6.0))  # thumb
    ax0, ay0 = at(base_along + 90.0, 20.0)
    ax1, ay1 = at(base_along + 200.0, 20.0)
    ax2, ay2 = at(base_along + 420.0, 20.0)
    parts.append(Capsule(ax0, ay0, ax1, ay1, 30.0 * k, base_h + 45.0))  # wrist and forearm, rising away
    parts.append(Capsule(ax1, ay1, ax2, ay2, 34.0 * k, base_h + 110.0))

    contacts: list[Ellipse] = []
    if pose.pressed:
        press = min(max(pose.press, 0.0), 1.3)
        contacts.append(Ellipse(pose.x, pose.y, 6.0 * k * press, 4.8 * k * press, angle, 0.0))
        if pose.spread_mm > 0.0:
            sx, sy = at(0.0, pose.spread_mm)
            contacts.append(Ellipse(sx, sy, 6.0 * k * press, 4.8 * k * press, angle, 0.0))
    return parts, contacts


def flat_hand_parts(pose: HandPose, px_per_mm: float) -> tuple[list[Part], list[Ellipse]]:
    """A hand held flat ``tip_mm`` above the membrane (0: pressed), palm centred on (x, y); see the module docstring."""
    k = px_per_mm * pose.size
    ux, uy = math.cos(pose.heading), math.sin(pose.heading)
    side = -1.0 if pose.left else 1.0
    nx, ny = -uy * side, ux * side
    h0 = max(pose.tip_mm, 0.0)
    angle = math.degrees(pose.heading)

    def at(along_mm: float, across_mm: float) -> tuple[float, float]:
        return pose.x + (ux * along_mm + nx * across_mm) * k, pose.y + (uy * along_mm + ny * across_mm) * k

    press = min(max(pose.press, 0.0), 1.3)
    # (along, across, semi-axis along, semi-axis across, angle offset deg): the palm's pads, fingers, thumb.
    pads = [(0.0, 0.0, 36.0, 32.0, 0.0)]
    pads += [(-71.0, across, 38.0, 8.0, 0.0) for across in (-24.0, -8.0, 8.0, 24.0)]  # 3 mm into the palm
    pads.append((-5.0, 40.0, 25.0, 9.0, -35.0))
    # The whole hand is opaque: the palm's outline (85 x 90 mm) shades the hollow between the pads, 5 mm up.
    parts: list[Part] = [Ellipse(*at(-10.0, 0.0), 48.0 * k, 44.0 * k, angle, h0 + 5.0)]
    contacts: list[Ellipse] = []
    for along, across, a, b, turn in pads:
        cx, cy = at(along, across)
        parts.append(Ellipse(cx, cy, a * k, b * k, angle + turn, h0))
        if pose.pressed:
            # The footprint grows as the hand presses: its edge is where the skin reaches the membrane.
            contacts.append(Ellipse(cx, cy, a * k * min(press, 1.0), b * k * min(press, 1.0), angle + turn, 0.0))
    ax0, ay0 = at(45.0, 0.0)
    ax1, ay1 = at(180.0, 0.0)
    ax2, ay2 = at(400.0, 0.0)
    parts.append(Capsule(ax0, ay0, ax1, ay1, 30.0 * k, h0 + 25.0))  # wrist and forearm, rising away
    parts.append(Capsule(ax1, ay1, ax2, ay2, 34.0 * k, h0 + 90.0))
    return parts, contacts


@dataclass(frozen=True)
class Blob:
    """A large soft occluder far from the membrane: a body or head leaning past (px, mm)."""

    x: float
    y: float
    radius_x: float
    radius_y: float
    height_mm: float

    def parts(self) -> list[Part]:
        return [Ellipse(self.x, self.y, self.radius_x, self.radius_y, 0.0, self.height_mm)]
