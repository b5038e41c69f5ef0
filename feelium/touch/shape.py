"""What touched: a finger, a palm or a hug, from the footprint of the contact on the membrane.

The footprint is the candidate's deep core (skin in optical contact darkens
the membrane far more than anything above it, see :mod:`feelium.touch.candidates`),
measured by its pixel count and second moments: a uniform ellipse of semi-axes
``a >= b`` has variances ``a^2 / 4`` and ``b^2 / 4`` along its axes, so the full
axes are ``4 sqrt(lambda)`` of the covariance's eigenvalues.

The thresholds are physical sizes of hands and bodies, never tuned on scores
(the defaults are argued in ``docs/touch.md``, *Contact shape*):

- a fingertip pad pressed on a soft membrane is 1 to 2.5 cm^2, a thumb pressed
  hard under 4 cm^2 and two fingers held together under 8 cm^2, while the heel
  of a palm alone is about 4 x 4 cm: ``palm_min_area_mm2`` (15 cm^2) sits between;
- the whole palmar side of a large adult hand, fingers included, is about
  1 % of the body's surface, 180-200 cm^2, and a flat hand touches less than
  that (the hollow of the palm stays off): ``hug_min_area_mm2`` (200 cm^2) is
  more than any one hand can cover; a forearm laid along the skin is narrower
  but longer than any hand (wrist to fingertip 17-21 cm): a palm-sized
  footprint at least ``hug_min_length_mm`` (23 cm) long is a hug too.
"""

from __future__ import annotations

import math

from feelium.events import ContactKind, ContactShape
from feelium.touch.config import TouchConfig

NOMINAL_PX_PER_MM = 2.0  # the simulator's and the paper's 640x480 rear camera over the front face


def axes_from_moments(cxx: float, cyy: float, cxy: float) -> tuple[float, float, float]:
    """(major, minor, orientation in degrees 0..180) of the uniform ellipse with this covariance (px^2)."""
    half_trace = 0.5 * (cxx + cyy)
    root = math.sqrt(max(0.25 * (cxx - cyy) ** 2 + cxy * cxy, 0.0))
    major = 4.0 * math.sqrt(max(half_trace + root, 0.0))
    minor = 4.0 * math.sqrt(max(half_trace - root, 0.0))
    orientation = math.degrees(0.5 * math.atan2(2.0 * cxy, cxx - cyy)) % 180.0
    return major, minor, orientation


def classify(config: TouchConfig, area_mm2: float, major_mm: float) -> ContactKind:
    """finger, palm or hug from the footprint's area and length (mm^2, mm)."""
    if area_mm2 >= config.hug_min_area_mm2:
        return "hug"
    if area_mm2 >= config.palm_min_area_mm2:
        return "hug" if major_mm >= config.hug_min_length_mm else "palm"
    return "finger"


def contact_shape(config: TouchConfig, area_px: float, cov_px: tuple[float, float, float]) -> ContactShape:
    """The footprint's shape from its area and covariance in camera pixels.

    Figures in mm need ``px_per_mm``; with it unknown (0) they are None and the
    classification assumes :data:`NOMINAL_PX_PER_MM`.
    """
    major, minor, orientation = axes_from_moments(*cov_px)
    scale = config.px_per_mm if config.px_per_mm > 0 else NOMINAL_PX_PER_MM
    kind = classify(config, area_px / scale**2, major / scale)
    elongation = major / max(minor, 1.0)
    if config.px_per_mm <= 0:
        return ContactShape(kind, None, None, None, elongation, orientation)
    return ContactShape(kind, area_px / scale**2, major / scale, minor / scale, elongation, orientation)


_RANK: dict[ContactKind, int] = {"finger": 0, "palm": 1, "hug": 2}


def larger(a: ContactKind, b: ContactKind) -> ContactKind:
    """The larger of two kinds: a palm that lands heel first, or a hug that grows, keeps its largest kind."""
    return a if _RANK[a] >= _RANK[b] else b
