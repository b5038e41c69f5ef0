"""Shadows on a diffusing membrane: how a hand outside darkens what the camera sees.

Model (see ``docs/simulator.md`` for the reasoning):

- A part of the hand at height ``h`` above the membrane blocks the diffuse room
  light that would reach the membrane from outside. For a Lambertian sky, the
  irradiance a point loses behind a thin occluder is the occluder's footprint
  convolved with the kernel ``h^2 / (pi (h^2 + rho^2)^2)``: its width grows
  linearly with ``h`` and a small part's peak fades as ``r^2 / (r^2 + h^2)``.
  We approximate that kernel by a Gaussian with ``sigma = sigma0 + k * h``
  (``k = 1/sqrt(2)`` matches the hemisphere's centre value; real rooms light
  from a narrower cone, so ``k`` is a session parameter) and multiply by a fill
  term ``exp(-h / h_fill)`` for light the room scatters back under a distant
  occluder. ``sigma0`` is the membrane's own lateral scatter.
- Where skin touches the membrane (height exactly 0) it also frustrates the
  membrane's internal reflection, so light couples into the finger and is lost:
  the contact patch gets an extra, sharp darkening that no hover produces.

Parts are ellipses and capsules with one height each; a finger that rises from
its pressed tip is a chain of capsules at increasing heights. Each part is
drawn anti-aliased into its own crop (at reduced resolution when its blur is
wide), blurred, and combined by maximum occlusion (overlapping parts of one
opaque hand do not double-darken). Pure: parts in, arrays out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

_SHIFT = 4  # sub-pixel precision of cv2 drawing: coordinates in 1/16 px
_ONE = 1 << _SHIFT


@dataclass(frozen=True)
class ShadowParams:
    """How a session's room light and membrane turn occluders into shadows."""

    px_per_mm: float = 2.0  # camera pixels per millimetre on the membrane (ROI 512 px ~ 256 mm)
    sigma0_px: float = 1.0  # the membrane's own lateral scatter
    spread_per_mm: float = 0.6  # blur growth: sigma grows by this many mm per mm of height
    fill_mm: float = 220.0  # contrast fill for distant occluders: exp(-h / fill_mm)
    outside_share: float = 0.55  # share of the membrane's brightness an occluder can block (room light)
    contact_depth: float = 0.55  # extra loss under skin in optical contact (frustrated reflection)

    def sigma_px(self, height_mm: float) -> float:
        return self.sigma0_px + self.spread_per_mm * self.px_per_mm * max(height_mm, 0.0)

    def fill(self, height_mm: float) -> float:
        return math.exp(-max(height_mm, 0.0) / self.fill_mm)


@dataclass(frozen=True)
class Ellipse:
    """A flat part: centre and semi-axes in camera px, rotation in degrees, height in mm."""

    cx: float
    cy: float
    ax: float
    ay: float
    angle_deg: float
    height_mm: float


@dataclass(frozen=True)
class Capsule:
    """A limb segment: a thick line from (x0, y0) to (x1, y1) of ``radius`` px at ``height_mm``."""

    x0: float
    y0: float
    x1: float
    y1: float
    radius: float
    height_mm: float


Part = Ellipse | Capsule


def _extent(part: Part) -> tuple[float, float, float, float]:
    if isinstance(part, Ellipse):
        r = max(part.ax, part.ay)
        return part.cx - r, part.cy - r, part.cx + r, part.cy + r
    r = part.radius
    return min(part.x0, part.x1) - r, min(part.y0, part.y1) - r, max(part.x0, part.x1) + r, max(part.y0, part.y1) + r


def _draw(canvas: np.ndarray, part: Part, ox: float, oy: float, scale: float) -> None:
    """Fill ``part`` (shifted by -ox, -oy, then scaled) into ``canvas`` anti-aliased with value 255."""

    def fx(v: float, o: float) -> int:
        return int(round((v - o) * scale * _ONE))

    if isinstance(part, Ellipse):
        axes = (max(1, int(round(part.ax * scale * _ONE))), max(1, int(round(part.ay * scale * _ONE))))
        cv2.ellipse(
            canvas, (fx(part.cx, ox), fx(part.cy, oy)), axes, part.angle_deg, 0, 360, 255, -1, cv2.LINE_AA, _SHIFT
        )
        return
    p0 = (fx(part.x0, ox), fx(part.y0, oy))
    p1 = (fx(part.x1, ox), fx(part.y1, oy))
    r = part.radius * scale
    thickness = max(1, int(round(2 * r)))
    cv2.line(canvas, p0, p1, 255, thickness, cv2.LINE_AA, _SHIFT)
    rr = max(1, int(round(r * _ONE)))
    cv2.circle(canvas, p0, rr, 255, -1, cv2.LINE_AA, _SHIFT)
    cv2.circle(canvas, p1, rr, 255, -1, cv2.LINE_AA, _SHIFT)


def blurred_footprint(
    part: Part, sigma: float, width: int, height: int
) -> tuple[tuple[int, int, int, int], np.ndarray] | None:
    """The part's footprint blurred by ``sigma`` px: ``((x0, y0, x1, y1), crop in 0..1)`` or None if off-frame."""
    ex0, ey0, ex1, ey1 = _extent(part)
    margin = 3.0 * sigma + 2.0
    x0, y0 = max(0, int(math.floor(ex0 - margin))), max(0, int(math.floor(ey0 - margin)))
    x1, y1 = min(width, int(math.ceil(ex1 + margin))), min(height, int(math.ceil(ey1 + margin)))
    if x1 <= x0 or y1 <= y0:
        return None
    # Wide blurs lose nothing at reduced resolution: blur small, then upsample. The part is drawn at
    # full resolution and area-averaged down, so its mass (and the blurred peak) does not jump when
    # the reduction factor changes with the height.
    factor = int(min(8, max(1, sigma // 3)))
    cw, ch = x1 - x0, y1 - y0
    sw, sh = max(1, -(-cw // factor)), max(1, -(-ch // factor))
    canvas = np.zeros((sh * factor, sw * factor), np.uint8)
    _draw(canvas, part, x0, y0, 1.0)
    small = canvas.astype(np.float32) * (1.0 / 255.0)
    if factor > 1:
        small = cv2.resize(small, (sw, sh), interpolation=cv2.INTER_AREA)
    small_sigma = sigma / factor
    if small_sigma > 0.3:
        small = cv2.GaussianBlur(small, (0, 0), small_sigma, borderType=cv2.BORDER_CONSTANT)
    if factor > 1:
        small = cv2.resize(small, (sw * factor, sh * factor), interpolation=cv2.INTER_LINEAR)[:ch, :cw]
    return (x0, y0, x1, y1), small


@dataclass(frozen=True)
class Shadow:
    """A frame's shadow: occlusion of outside light and the contact patches' extra loss, both 0..1."""

    occlusion: np.ndarray  # (H, W) float32
    contact: np.ndarray  # (H, W) float32

    def transmission(self, params: ShadowParams, room: float = 1.0) -> np.ndarray:
        """``S``: the factor the shadow multiplies the back-lit membrane by (room = outside light level)."""
        return self.lit_by(params, room, 1.0)

    def lit_by(self, params: ShadowParams, room: float, projected: float | np.ndarray) -> np.ndarray:
        """``S`` when the projector's share of the light is scaled by ``projected`` and the room's is not.

        The room light that comes in through the membrane does not follow what
        the projector shows, so a dark projected pixel leaves it unchanged.
        """
        outside = params.outside_share * room * (1.0 - self.occlusion)
        inside = (1.0 - params.outside_share) * projected
        return (inside + outside) * (1.0 - params.contact_depth * self.contact)


def render_shadow(
    parts: list[Part], contacts: list[Ellipse], params: ShadowParams, width: int, height: int
) -> Shadow:
    """Occlusion of every part (blurred by its height) and the sharp contact patches."""
    occlusion = np.zeros((height, width), np.float32)
    for part in parts:
        sigma = params.sigma_px(part.height_mm)
        found = blurred_footprint(part, sigma, width, height)
        if found is None:
            continue
        (x0, y0, x1, y1), crop = found
        np.maximum(occlusion[y0:y1, x0:x1], crop * params.fill(part.height_mm), out=occlusion[y0:y1, x0:x1])
    contact = np.zeros((height, width), np.float32)
    for patch in contacts:
        found = blurred_footprint(patch, params.sigma0_px, width, height)
        if found is None:
            continue
        (x0, y0, x1, y1), crop = found
        np.maximum(contact[y0:y1, x0:x1], crop, out=contact[y0:y1, x0:x1])
    return Shadow(occlusion, contact)
