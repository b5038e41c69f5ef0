"""The event objects that flow from the sensing cores to the bus, the headset and the projector.

Their JSON form is fixed by ``docs/evaluation.md`` (touch) and is what
`feelium replay` prints, what the HTTP API delivers and what `feelium eval`
scores, so there is exactly one definition of each here.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

TouchPhase = Literal["down", "move", "up"]
TouchKind = Literal["tap", "hold", "swipe"]
ContactKind = Literal["finger", "palm", "hug"]  # what touched (the contact's shape), beside the gesture in time
PresencePhase = Literal["approach", "update", "leave"]


def _rounded(value: float, digits: int) -> float | None:
    """JSON has no NaN: a non-finite measurement is reported as null."""
    if value is None or not math.isfinite(value):
        return None
    return round(float(value), digits)


@dataclass(frozen=True)
class ContactShape:
    """What touched, from the contact's footprint (the deep core of its shadow), for interactions that react
    to a palm or a hug rather than to a fingertip.

    ``area_mm2``, ``major_mm`` and ``minor_mm`` are None when the camera's scale on the membrane is unknown;
    ``elongation`` (major / minor) and ``orientation_deg`` (the major axis from the camera's x axis, image y
    down, 0..180) need no scale.
    """

    contact: ContactKind
    area_mm2: float | None
    major_mm: float | None
    minor_mm: float | None
    elongation: float
    orientation_deg: float

    def to_json(self) -> dict[str, Any]:
        return {
            "contact": self.contact,
            "contact_area_mm2": None if self.area_mm2 is None else _rounded(self.area_mm2, 0),
            "major_mm": None if self.major_mm is None else _rounded(self.major_mm, 1),
            "minor_mm": None if self.minor_mm is None else _rounded(self.minor_mm, 1),
            "elongation": _rounded(self.elongation, 2),
            "orientation_deg": _rounded(self.orientation_deg, 1),
        }


@dataclass(frozen=True)
class TouchEvent:
    """One phase of one contact on the membrane.

    ``t`` is the frame's time (in the daemon, its monotonic clock); ``x``/``y`` are camera pixels at the
    recording's full resolution; ``u``/``v`` run 0..1 across the ROI, or across the whole front face with a face model
    (:mod:`feelium.skin.face`: azimuth and elevation on the envelope). ``kind`` is the gesture in time (the
    spec's tap/hold/swipe); ``shape`` says what touched (finger, palm or hug) and its footprint.
    """

    id: int
    phase: TouchPhase
    kind: TouchKind | None
    t: float
    x: float
    y: float
    u: float
    v: float
    depth: float
    area: int
    anchor: float
    shape: ContactShape | None = None
    extra: dict[str, Any] = field(default_factory=dict, compare=False)

    def to_json(self) -> dict[str, Any]:
        """The spec's JSON object; ``extra`` keys (e.g. projector coordinates) are merged in."""
        obj: dict[str, Any] = {
            "id": self.id,
            "phase": self.phase,
            "kind": self.kind,
            "t": _rounded(self.t, 4),
            "x": _rounded(self.x, 1),
            "y": _rounded(self.y, 1),
            "u": _rounded(self.u, 3),
            "v": _rounded(self.v, 3),
            "depth": _rounded(self.depth, 3),
            "area": int(self.area),
            "anchor": _rounded(self.anchor, 3),
        }
        if self.shape is not None:
            obj.update(self.shape.to_json())
        obj.update(self.extra)
        return obj


@dataclass(frozen=True)
class PresenceEvent:
    """A warm body near the blimp, seen by the thermal camera (never a touch decision).

    ``x``/``y`` are the cluster's centroid in sensor pixels (32x24, row 0 at
    the top); ``azimuth_deg``/``elevation_deg`` are bearings through the
    lens's field of view, positive to the right and up.
    """

    phase: PresencePhase
    t: float
    x: float
    y: float
    azimuth_deg: float
    elevation_deg: float
    size: int
    peak_rise_c: float

    def to_json(self) -> dict[str, Any]:
        obj = asdict(self)
        for key in ("t", "x", "y", "azimuth_deg", "elevation_deg", "peak_rise_c"):
            obj[key] = _rounded(obj[key], 3)
        return obj


WearerActionName = Literal["heart", "palm_raise", "palm_lower", "shimmer", "guess"]


@dataclass(frozen=True)
class WearerAction:
    """Something the wearer did in the headset that the interaction engine answers.

    ``heart`` (the pinch that sends a heart back), ``palm_raise``/``palm_lower``,
    ``shimmer`` (invite the partner's hand) and ``guess`` (``detail["word"]``).
    """

    action: WearerActionName
    t: float
    detail: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"action": self.action, "t": _rounded(self.t, 4), **self.detail}


@dataclass(frozen=True)
class InteractionEvent:
    """An exchange the interaction engine recognised, for the wearer's view.

    ``name`` is the exchange (``greeting_pat``, ``palm_to_palm``, ``peck``,
    ``drawing``, ``hug``, ``invite``); ``phase`` its step (e.g. ``start``,
    ``stroke``, ``ignite``, ``end``); ``x``/``y`` camera pixels when located.
    """

    name: str
    phase: str
    t: float
    x: float | None = None
    y: float | None = None
    region: str | None = None
    detail: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        obj = asdict(self)
        obj["t"] = _rounded(self.t, 4)
        obj.pop("detail")
        obj.update(self.detail)
        return obj



# Speech on the bus: audio travels as bounded bus items like every other event, so the HTTP link and the
# audio device never call each other and a slow side only loses audio.


@dataclass(frozen=True)
class SpeechIn:
    """Wearer speech to play in the room: PCM16 mono little-endian at ``rate``."""

    pcm: bytes
    rate: int
    t: float


@dataclass(frozen=True)
class SpeechOut:
    """Room sound captured on the blimp for the wearer: PCM16 mono little-endian at ``rate``."""

    pcm: bytes
    rate: int
    t: float
