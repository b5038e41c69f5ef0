"""What happens in each trial and clip of the paper's protocol, as scripts of tracks.

A :class:`Script` is pure data: the hands and bodies with their keyframes,
contact intervals, room light and exposure over time. ``state(t)`` gives the
scene at any camera time and ``labels()`` the ground truth from the same
numbers, so frames and labels cannot disagree. Builders draw every random
choice from the RNG they are given, so a seed fixes the whole trial.

Timing follows the paper's protocol: trials of a few seconds with the contact
in the middle; taps touch for 0.1-0.3 s, holds for 1.2-2.5 s, swipes move
40-200 px while touching; hovers come within 2-30 mm (most within 10 mm) and
stay; disturbances sweep or wave a hand 10-60 mm above the membrane or pass a
body's large soft shadow; empty scenes drift in exposure and some see the room
light switched.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from feelium.recording import Contact, Labels
from feelium.sim.hand import HandPose
from feelium.sim.hand_paths import BlobTrack, HandTrack, Keyframe, Tremor
from feelium.sim.scene import SceneState

Roi = tuple[int, int, int, int]
FAR_MM = 150.0  # a hand this high casts only a faint, very wide shadow


@dataclass(frozen=True)
class Script:
    """One recording's story: tracks, lighting and the truth to label it with."""

    label: str
    duration: float
    hands: tuple[HandTrack, ...] = ()
    blobs: tuple[BlobTrack, ...] = ()
    target: tuple[float, float] | None = None
    clip: bool = False
    room_steps: tuple[tuple[float, float], ...] = ()  # (time, new outside light level)
    exposure_amp: float = 0.0  # auto-exposure hunting amplitude, relative
    exposure_period_s: float = 7.0
    exposure_phase: float = 0.0
    params: dict[str, Any] = field(default_factory=dict)  # what was drawn, for meta["generator"]

    def room(self, t: float) -> float:
        level = 1.0
        for when, value in self.room_steps:
            if t >= when:
                level = value
        return level

    def exposure(self, t: float) -> float:
        return 1.0 + self.exposure_amp * math.sin(2 * math.pi * t / self.exposure_period_s + self.exposure_phase)

    def hand_poses(self, t: float) -> tuple[HandPose, ...]:
        """The hands present at ``t`` (also what the thermal channel needs)."""
        return tuple(p for p in (h.pose(t) for h in self.hands) if p is not None)

    def state(self, t: float) -> SceneState:
        return SceneState(
            hands=self.hand_poses(t),
            blobs=tuple(b.blob(t) for b in self.blobs),
            room=self.room(t),
            exposure=self.exposure(t),
        )

    def labels(self) -> Labels:
        contacts = []
        for hand in self.hands:
            for on, off in hand.contacts:
                contacts.append(Contact(on, off, hand.contact_path(on, off)))
        contacts.sort(key=lambda c: c.t_on)
        return Labels(label=self.label, clip=self.clip, target=self.target, contacts=tuple(contacts))


def prompted_targets(roi: Roi) -> list[tuple[float, float]]:
    """The nine prompted landing points: a 3 x 3 grid at 20/50/80 % of the patch."""
    x, y, w, h = roi
    return [(x + fx * w, y + fy * h) for fy in (0.2, 0.5, 0.8) for fx in (0.2, 0.5, 0.8)]


def _clamp_to_roi(x: float, y: float, roi: Roi, margin: float = 16.0) -> tuple[float, float]:
    rx, ry, rw, rh = roi
    return min(max(x, rx + margin), rx + rw - margin), min(max(y, ry + margin), ry + rh - margin)


def _posture(rng: np.random.Generator) -> dict[str, Any]:
    """Arm from below (the partner stands in front), some turn; either hand; a size."""
    return {
        "heading": float(math.pi / 2 + rng.uniform(-0.7, 0.7)),
        "pitch_deg": float(rng.uniform(25.0, 50.0)),
        "size": float(rng.uniform(0.85, 1.15)),
        "left": bool(rng.random() < 0.3),
    }


def _offscreen_from(x: float, y: float, heading: float, distance: float) -> tuple[float, float]:
    """A point ``distance`` px from (x, y) towards the wrist: where the hand comes from and goes to."""
    return x + math.cos(heading) * distance, y + math.sin(heading) * distance


def _reach(
    rng: np.random.Generator,
    land: tuple[float, float],
    t_on: float,
    t_off: float,
    duration: float,
    posture: dict[str, Any],
    during: list[Keyframe] | None = None,
) -> tuple[Keyframe, ...]:
    """Keyframes of a hand coming in from far, landing at ``t_on``, leaving after ``t_off``."""
    lx, ly = land
    sx, sy = _offscreen_from(lx, ly, posture["heading"] + rng.uniform(-0.4, 0.4), rng.uniform(80, 200))
    approach = rng.uniform(0.35, 0.7)
    near = (lx + rng.normal(0, 6), ly + rng.normal(0, 6))
    keys = [Keyframe(0.0, sx, sy, FAR_MM), Keyframe(t_on - approach, *near, rng.uniform(15.0, 35.0))]
    keys.append(Keyframe(t_on, lx, ly, 0.0))
    keys += during or []
    end = during[-1] if during else Keyframe(t_off, lx, ly, 0.0)
    if not during:
        keys.append(end)
    lift = rng.uniform(0.25, 0.45)
    keys.append(Keyframe(t_off + lift, end.x + rng.normal(0, 5), end.y + rng.normal(0, 5), rng.uniform(20.0, 40.0)))
    ex, ey = _offscreen_from(end.x, end.y, posture["heading"] + rng.uniform(-0.4, 0.4), rng.uniform(100, 220))
    keys.append(Keyframe(max(duration, t_off + lift + 0.3), ex, ey, FAR_MM))
    return tuple(keys)


def _touch_track(keys: tuple[Keyframe, ...], contacts: tuple[tuple[float, float], ...], rng, posture) -> HandTrack:
    return HandTrack(keys=keys, contacts=contacts, tremor=Tremor.draw(rng), **posture)


def tap(rng: np.random.Generator, target: tuple[float, float], aim: tuple[float, float], roi: Roi) -> Script:
    """A short touch (0.1-0.3 s) at the prompted target (missed by ``aim`` px)."""
    duration = float(rng.uniform(3.0, 5.0))
    t_on = float(rng.uniform(0.4, 0.6) * duration)
    t_off = t_on + float(rng.uniform(0.1, 0.3))
    land = _clamp_to_roi(target[0] + aim[0], target[1] + aim[1], roi)
    posture = _posture(rng)
    keys = _reach(rng, land, t_on, t_off, duration, posture)
    hand = _touch_track(keys, ((t_on, t_off),), rng, posture)
    return Script("tap", duration, (hand,), target=target, params={"land": land, **posture})


def hold(rng: np.random.Generator, target: tuple[float, float], aim: tuple[float, float], roi: Roi) -> Script:
    """A long press (1.2-2.5 s) with a little finger roll."""
    t_on = float(rng.uniform(0.9, 1.5))
    length = float(rng.uniform(1.2, 2.5))
    t_off = t_on + length
    duration = max(float(rng.uniform(3.0, 5.0)), t_off + float(rng.uniform(0.9, 1.4)))
    land = _clamp_to_roi(target[0] + aim[0], target[1] + aim[1], roi)
    roll = (land[0] + rng.normal(0, 1.5), land[1] + rng.normal(0, 1.5))
    posture = _posture(rng)
    during = [Keyframe(t_off, *roll, 0.0)]
    keys = _reach(rng, land, t_on, t_off, duration, posture, during)
    hand = _touch_track(keys, ((t_on, t_off),), rng, posture)
    return Script("hold", duration, (hand,), target=target, params={"land": land, **posture})


def swipe(rng: np.random.Generator, target: tuple[float, float], aim: tuple[float, float], roi: Roi) -> Script:
    """A stroke: lands at the target and slides 40-200 px in 0.4-1.0 s before lifting."""
    t_on = float(rng.uniform(1.0, 1.6))
    length_s = float(rng.uniform(0.4, 1.0))
    t_off = t_on + length_s
    duration = max(float(rng.uniform(3.0, 5.0)), t_off + 1.0)
    land = _clamp_to_roi(target[0] + aim[0], target[1] + aim[1], roi)
    rx, ry, rw, rh = roi
    centre = (rx + rw / 2, ry + rh / 2)
    towards = math.atan2(centre[1] - land[1], centre[0] - land[0])  # strokes head into the patch
    angle = towards + float(rng.uniform(-0.9, 0.9))
    dist = float(rng.uniform(40.0, 200.0))
    end = _clamp_to_roi(land[0] + math.cos(angle) * dist, land[1] + math.sin(angle) * dist, roi)
    if math.hypot(end[0] - land[0], end[1] - land[1]) < 40.0:  # clamped against an edge: go back the other way
        end = _clamp_to_roi(land[0] - math.cos(angle) * dist, land[1] - math.sin(angle) * dist, roi)
    posture = _posture(rng)
    keys = _reach(rng, land, t_on, t_off, duration, posture, [Keyframe(t_off, *end, 0.0)])
    hand = _touch_track(keys, ((t_on, t_off),), rng, posture)
    return Script("swipe", duration, (hand,), target=target, params={"land": land, "end": end, **posture})


def hover_height(rng: np.random.Generator) -> float:
    """Hover heights: most within 10 mm (the hard negatives), some up to 30 mm."""
    u = rng.random()
    if u < 0.4:
        return float(rng.uniform(2.0, 4.0))
    if u < 0.8:
        return float(rng.uniform(4.0, 10.0))
    return float(rng.uniform(10.0, 30.0))


def hover(rng: np.random.Generator, target: tuple[float, float], aim: tuple[float, float], roi: Roi) -> Script:
    """A hand comes close over the target and stays, wobbling, without touching."""
    duration = float(rng.uniform(3.0, 5.0))
    t1 = float(rng.uniform(0.3, 0.45) * duration)
    stay = float(rng.uniform(1.0, 2.5))
    t2 = min(t1 + stay, duration - 0.8)
    h1, h2 = hover_height(rng), hover_height(rng)
    p = _clamp_to_roi(target[0] + aim[0], target[1] + aim[1], roi)
    posture = _posture(rng)
    sx, sy = _offscreen_from(p[0], p[1], posture["heading"], rng.uniform(80, 200))
    ex, ey = _offscreen_from(p[0], p[1], posture["heading"] + rng.uniform(-0.4, 0.4), rng.uniform(100, 220))
    keys = (
        Keyframe(0.0, sx, sy, FAR_MM),
        Keyframe(t1 - rng.uniform(0.4, 0.7), p[0] + rng.normal(0, 6), p[1] + rng.normal(0, 6), 30.0),
        Keyframe(t1, *p, h1),
        Keyframe(t2, p[0] + rng.normal(0, 4), p[1] + rng.normal(0, 4), h2),
        Keyframe(t2 + 0.4, p[0], p[1], 35.0),
        Keyframe(max(duration, t2 + 0.7), ex, ey, FAR_MM),
    )
    tremor = Tremor.draw(rng, drift_mm=float(rng.uniform(0.3, 0.4) * min(h1, h2)))
    hand = HandTrack(keys=keys, tremor=tremor, **posture)
    return Script("hover", duration, (hand,), target=None, params={"heights_mm": (h1, h2), **posture})


def disturbance(rng: np.random.Generator, kind: str, roi: Roi) -> Script:
    """No contact: a hand sweeping past, a hand waving, or a body's shadow passing."""
    duration = float(rng.uniform(3.0, 5.0))
    rx, ry, rw, rh = roi
    if kind == "body":
        cy = ry + rh * rng.uniform(0.3, 0.7)
        left_to_right = rng.random() < 0.5
        x0, x1 = (rx - 250, rx + rw + 250) if left_to_right else (rx + rw + 250, rx - 250)
        t0, t1 = 0.2 * duration, 0.95 * duration
        keys = (Keyframe(t0, x0, cy, 0.0), Keyframe(t1, x1, cy + rng.normal(0, 40), 0.0))
        height = float(rng.uniform(150.0, 400.0))
        body = BlobTrack(keys, float(rng.uniform(120, 220)), float(rng.uniform(160, 260)), height)
        return Script("disturbance", duration, blobs=(body,), params={"kind": kind, "height_mm": height})
    posture = _posture(rng)
    posture["open_hand"] = bool(rng.random() < 0.6)
    height = float(rng.uniform(10.0, 60.0))
    if kind == "sweep":
        y0 = ry + rh * rng.uniform(0.2, 0.8)
        left_to_right = rng.random() < 0.5
        x0, x1 = (rx - 120, rx + rw + 120) if left_to_right else (rx + rw + 120, rx - 120)
        speed = float(rng.uniform(200.0, 600.0))
        t0 = float(rng.uniform(0.5, 1.2))
        t1 = min(duration - 0.2, t0 + abs(x1 - x0) / speed)
        keys = (
            Keyframe(0.0, x0, y0, FAR_MM),
            Keyframe(t0, x0, y0, height),
            Keyframe(t1, x1, y0 + rng.normal(0, 40), max(10.0, height + rng.normal(0, 5))),
            Keyframe(duration, x1, y0, FAR_MM),
        )
    elif kind == "wave":
        cx, cy = rx + rw * rng.uniform(0.3, 0.7), ry + rh * rng.uniform(0.3, 0.7)
        amp = float(rng.uniform(60.0, 120.0))
        half = 0.5 / float(rng.uniform(1.5, 3.0))
        t = float(rng.uniform(0.6, 1.2))
        frames = [Keyframe(0.0, cx, cy + 150, FAR_MM), Keyframe(t, cx, cy, height)]
        side = 1.0
        while t + half < duration - 0.6:
            t += half
            frames.append(Keyframe(t, cx + side * amp, cy + rng.normal(0, 8), max(10.0, height + rng.normal(0, 3))))
            side = -side
        frames.append(Keyframe(duration, cx, cy + 150, FAR_MM))
        keys = tuple(frames)
    else:
        raise ValueError(f"unknown disturbance kind {kind!r}; expected sweep, wave or body")
    hand = HandTrack(keys=keys, tremor=Tremor.draw(rng, drift_mm=1.0), **posture)
    return Script("disturbance", duration, (hand,), params={"kind": kind, "height_mm": height, **posture})


DISTURBANCE_KINDS = ("sweep", "wave", "body")


def empty(rng: np.random.Generator, *, lighting_step: bool) -> Script:
    """Nobody there: exposure hunting, and optionally the room light switched on or off."""
    duration = float(rng.uniform(3.0, 5.0))
    steps: tuple[tuple[float, float], ...] = ()
    if lighting_step:
        level = float(rng.choice([rng.uniform(0.4, 0.7), rng.uniform(1.3, 1.8)]))
        steps = ((float(rng.uniform(0.3, 0.7) * duration), level),)
    return Script(
        "empty",
        duration,
        room_steps=steps,
        exposure_amp=float(rng.uniform(0.01, 0.06)),
        exposure_period_s=float(rng.uniform(3.0, 10.0)),
        exposure_phase=float(rng.uniform(0, 2 * math.pi)),
        params={"lighting_steps": steps},
    )


def contact_clip(rng: np.random.Generator, duration: float, roi: Roi) -> Script:
    """Steady contact: long presses (12-25 s) at a few spots, with short lifts between."""
    rx, ry, rw, rh = roi
    posture = _posture(rng)
    t = float(rng.uniform(1.0, 2.0))
    p = (rx + rw * rng.uniform(0.3, 0.7), ry + rh * rng.uniform(0.3, 0.7))
    sx, sy = _offscreen_from(p[0], p[1], posture["heading"], 150)
    keys = [Keyframe(0.0, sx, sy, FAR_MM), Keyframe(t - 0.5, p[0], p[1], 25.0)]
    contacts = []
    while t < duration - 3.0:
        length = min(float(rng.uniform(12.0, 25.0)), duration - 1.5 - t)
        keys.append(Keyframe(t, *p, 0.0))
        roll = (p[0] + rng.normal(0, 2), p[1] + rng.normal(0, 2))
        keys.append(Keyframe(t + length, *roll, 0.0))
        contacts.append((t, t + length))
        t += length
        if t > duration - 5.0:
            break
        gap = float(rng.uniform(1.0, 2.5))
        p = _clamp_to_roi(roll[0] + rng.normal(0, 60), roll[1] + rng.normal(0, 40), roi, 40)
        keys.append(Keyframe(t + gap / 2, (roll[0] + p[0]) / 2, (roll[1] + p[1]) / 2, float(rng.uniform(5, 20))))
        t += gap
    ex, ey = _offscreen_from(p[0], p[1], posture["heading"], 200)
    keys.append(Keyframe(t + 0.4, p[0], p[1], 30.0))
    keys.append(Keyframe(duration, ex, ey, FAR_MM))
    hand = HandTrack(keys=tuple(keys), contacts=tuple(contacts), tremor=Tremor.draw(rng), **posture)
    return Script("contact", duration, (hand,), clip=True, params=dict(posture))


def hover_clip(rng: np.random.Generator, duration: float, roi: Roi) -> Script:
    """Hovering: a hand lingering 2-12 mm above the patch, moving between spots, never touching."""
    rx, ry, rw, rh = roi
    posture = _posture(rng)
    p = (rx + rw * rng.uniform(0.3, 0.7), ry + rh * rng.uniform(0.3, 0.7))
    sx, sy = _offscreen_from(p[0], p[1], posture["heading"], 150)
    keys = [Keyframe(0.0, sx, sy, FAR_MM)]
    t = float(rng.uniform(1.0, 2.0))
    while t < duration - 2.0:
        keys.append(Keyframe(t, *p, float(rng.uniform(2.0, 12.0))))
        t += float(rng.uniform(3.0, 8.0))
        p = _clamp_to_roi(p[0] + rng.normal(0, 50), p[1] + rng.normal(0, 35), roi, 40)
    keys.append(Keyframe(duration - 1.0, *p, float(rng.uniform(2.0, 12.0))))
    keys.append(Keyframe(duration, *_offscreen_from(p[0], p[1], posture["heading"], 200), FAR_MM))
    tremor = Tremor.draw(rng, drift_mm=float(rng.uniform(0.8, 1.5)))
    hand = HandTrack(keys=tuple(keys), tremor=tremor, **posture)
    return Script("hover", duration, (hand,), clip=True, params=dict(posture))


def empty_clip(rng: np.random.Generator, duration: float) -> Script:
    """Nobody there for the whole clip: exposure drift only."""
    return Script(
        "empty",
        duration,
        clip=True,
        exposure_amp=float(rng.uniform(0.01, 0.04)),
        exposure_period_s=float(rng.uniform(15.0, 30.0)),
        exposure_phase=float(rng.uniform(0, 2 * math.pi)),
    )


TrialBuilder = Callable[[np.random.Generator, tuple[float, float], tuple[float, float], Roi], Script]
PROMPTED: dict[str, TrialBuilder] = {"tap": tap, "hold": hold, "swipe": swipe, "hover": hover}
