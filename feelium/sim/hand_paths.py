"""How hands and bodies move over time: keyframed reaches with tremor and drift.

Human reaching is well described by minimum-jerk trajectories between via
points (Flash and Hogan 1985), so tracks interpolate keyframes with the
minimum-jerk profile ``10s^3 - 15s^4 + 6s^5``. A hand held in the air is never
still: physiological tremor (8 to 12 Hz, a few tenths of a mm) rides on a slow
postural drift (tenths of a Hz, a few mm). A pressed fingertip is pinned by
friction, so while in contact neither applies and the height is exactly 0.

A :class:`HandTrack` knows its contact intervals, so the labelled contacts and
what is rendered come from the same numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from feelium.sim.body import Lean
from feelium.sim.hand import Blob, HandPose

HOVER_FLOOR_MM = 0.8  # a hand that is not touching never gets closer than this


def min_jerk(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


@dataclass(frozen=True)
class Keyframe:
    t: float
    x: float
    y: float
    h: float  # height in mm (or any scalar the track carries)


def interpolate(keys: tuple[Keyframe, ...], t: float) -> tuple[float, float, float]:
    """Position at ``t`` along minimum-jerk segments; held constant before the first and after the last key."""
    if t <= keys[0].t:
        k = keys[0]
        return k.x, k.y, k.h
    for a, b in zip(keys[:-1], keys[1:]):
        if t < b.t:
            s = min_jerk((t - a.t) / max(b.t - a.t, 1e-9))
            return a.x + (b.x - a.x) * s, a.y + (b.y - a.y) * s, a.h + (b.h - a.h) * s
    k = keys[-1]
    return k.x, k.y, k.h


@dataclass(frozen=True)
class Tremor:
    """Physiological tremor plus slow postural drift, as sums of sines with fixed phases."""

    freq_hz: float = 10.0
    amp_mm: float = 0.35  # height tremor amplitude
    amp_px: float = 1.0  # in-plane tremor amplitude
    drift_hz: float = 0.25
    drift_mm: float = 1.5
    drift_px: float = 4.0
    phases: tuple[float, ...] = (0.0, 1.0, 2.0, 3.0, 4.0, 5.0)

    @staticmethod
    def draw(rng: np.random.Generator, *, drift_mm: float | None = None) -> "Tremor":
        return Tremor(
            freq_hz=float(rng.uniform(8.0, 12.0)),
            amp_mm=float(rng.uniform(0.2, 0.5)),
            amp_px=float(rng.uniform(0.6, 1.4)),
            drift_hz=float(rng.uniform(0.1, 0.5)),
            drift_mm=float(rng.uniform(0.5, 2.5)) if drift_mm is None else drift_mm,
            drift_px=float(rng.uniform(2.0, 8.0)),
            phases=tuple(float(p) for p in rng.uniform(0, 2 * math.pi, 6)),
        )

    def offset(self, t: float) -> tuple[float, float, float]:
        """(dx px, dy px, dh mm) at ``t``."""
        p = self.phases
        w, d = 2 * math.pi * self.freq_hz, 2 * math.pi * self.drift_hz
        # A second, detuned tremor line keeps the wobble from being a pure sine.
        dh = self.amp_mm * (0.75 * math.sin(w * t + p[0]) + 0.25 * math.sin(1.37 * w * t + p[1]))
        dh += self.drift_mm * (0.6 * math.sin(d * t + p[2]) + 0.4 * math.sin(2.3 * d * t + p[3]))
        dx = self.amp_px * math.sin(w * t + p[4]) + self.drift_px * math.sin(0.8 * d * t + p[5])
        dy = self.amp_px * math.cos(1.1 * w * t + p[4]) + self.drift_px * math.sin(0.9 * d * t + p[2] + p[5])
        return dx, dy, dh


@dataclass(frozen=True)
class HandTrack:
    """One hand over a recording: keyframed fingertip, contact intervals, tremor and posture."""

    keys: tuple[Keyframe, ...]
    contacts: tuple[tuple[float, float], ...] = ()
    tremor: Tremor = field(default_factory=Tremor)
    heading: float = math.pi / 2
    pitch_deg: float = 35.0
    size: float = 1.0
    open_hand: bool = False
    left: bool = False
    spread_mm: float = 0.0  # a V of two pressed fingertips this far apart (see HandPose)
    flat: bool = False  # the hand flat: the keys place the palm's centre
    t_in: float = -math.inf  # the hand is in the scene during [t_in, t_out)
    t_out: float = math.inf
    press_ramp_s: float = 0.04  # the contact patch grows and shrinks over this time
    pressure_wobble: float = 0.08  # relative variation of the contact patch during a long press

    def __post_init__(self) -> None:
        # Contact times are kept to the millisecond, as labels store them, so a frame can
        # never be rendered as touching while its label says otherwise.
        object.__setattr__(self, "contacts", tuple((round(on, 3), round(off, 3)) for on, off in self.contacts))

    def in_contact(self, t: float) -> bool:
        return any(on <= t < off for on, off in self.contacts)

    def _edge_fade(self, t: float) -> float:
        """Tremor and drift fade in over 0.15 s around contact edges, so approaches stay smooth."""
        if not self.contacts:
            return 1.0
        nearest = min(min(abs(t - on), abs(t - off)) for on, off in self.contacts)
        return min(1.0, nearest / 0.15)

    def fingertip(self, t: float) -> tuple[float, float, float]:
        """True fingertip (x px, y px, height mm) at ``t``; height is exactly 0 during contacts."""
        x, y, h = interpolate(self.keys, t)
        if self.in_contact(t):
            return x, y, 0.0
        dx, dy, dh = self.tremor.offset(t)
        fade = self._edge_fade(t)
        return x + fade * dx, y + fade * dy, max(HOVER_FLOOR_MM, h + fade * dh)

    def pose(self, t: float) -> HandPose | None:
        if not (self.t_in <= t < self.t_out):
            return None
        x, y, h = self.fingertip(t)
        press = 1.0
        for on, off in self.contacts:
            if on <= t < off:
                ramp = min(1.0, (t - on) / self.press_ramp_s, (off - t) / self.press_ramp_s)
                wobble = 1.0 + self.pressure_wobble * math.sin(2 * math.pi * 0.7 * (t - on) + self.tremor.phases[3])
                press = max(0.45, ramp) * wobble
        return HandPose(
            x, y, h, heading=self.heading, pitch_deg=self.pitch_deg, press=press,
            size=self.size, open_hand=self.open_hand, left=self.left, spread_mm=self.spread_mm, flat=self.flat,
        )  # fmt: skip

    def contact_path(self, on: float, off: float, rate_hz: float = 30.0) -> np.ndarray:
        """Rows ``[t, x, y]`` of the true fingertip over one contact, ends included."""
        n = max(2, int(math.ceil((off - on) * rate_hz)) + 1)
        ts = np.linspace(on, off, n)
        ts[-1] = off - 1e-6 if off - on > 2e-6 else off
        rows = [(t, *interpolate(self.keys, t)[:2]) for t in ts]
        return np.asarray(rows, dtype=np.float64)


@dataclass(frozen=True)
class BlobTrack:
    """A body or head drifting past: keyframed centre, fixed size and height."""

    keys: tuple[Keyframe, ...]  # h is unused; the height is fixed
    radius_x: float
    radius_y: float
    height_mm: float

    def blob(self, t: float) -> Blob:
        x, y, _ = interpolate(self.keys, t)
        return Blob(x, y, self.radius_x, self.radius_y, self.height_mm)


@dataclass(frozen=True)
class LeanTrack:
    """A body leaning in for a hug: keyframed centre and height (mm), pressed during ``contacts``."""

    keys: tuple[Keyframe, ...]
    contacts: tuple[tuple[float, float], ...] = ()
    settle_s: float = 0.3  # the chest's footprint spreads over this time as the body settles against the skin

    def lean(self, t: float) -> Lean:
        x, y, h = interpolate(self.keys, t)
        for on, off in self.contacts:
            if on <= t < off:
                return Lean(x, y, 0.0, press=max(0.2, min(1.0, (t - on) / self.settle_s, (off - t) / self.settle_s)))
        return Lean(x, y, max(h, HOVER_FLOOR_MM))
