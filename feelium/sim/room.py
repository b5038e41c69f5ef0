"""Room light through the membrane: a lamp or daylight that does not follow the back-light.

The sessions' ``outside_share`` is the dim room of the paper: light from
outside that is proportional to the projector's (mostly its own light returned
by the room), so a relative shadow depth does not see it change. A lit living
room adds light of its own, from lamps and windows, that:

- is *additive* and spatially its own: nearly uniform over the membrane (a
  gentle gradient towards the lamp), not shaped like the 4.5-7:1 back-light,
  so a switch changes the bright centre and the dim corners by different
  factors, not by one gain;
- comes from outside, so whatever is outside blocks it: a hand blocks it with
  the same height-blurred occlusion as the dim room's outside light (a hover
  casts a darker room-light shadow in a brighter room), a fingertip in contact
  blocks it completely at its core; the frustrated reflection under the skin
  concerns the projector's light only;
- changes: switched on or off (a step with a short ramp), drifts (daylight),
  and a person walking between the lamp and the blimp sweeps a very soft
  shadow across the whole membrane;
- is followed by the camera's auto-exposure, which keeps the membrane's mean
  level where the dim room had it, with a first-order lag.

Levels are fractions of the ROI's mean back-light (1.0: the room's light through
the membrane is as bright as the projector's). Pure data and pure functions of
time; the renderer (:class:`feelium.sim.scene.SceneRenderer`) applies them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

AE_STEP_S = 0.005  # integration step of the auto-exposure lag


@dataclass(frozen=True)
class Passer:
    """A person walking between the lamp and the blimp: a trapezoid of lamp-light loss sweeping along x.

    With the person halfway between a 0.3 m lamp shade and the membrane, the
    shadow moves at twice the walking speed and its penumbra is as wide as the
    shade (0.3 m = 600 px), wider than the ROI: the membrane dims gradually
    from one side, never with an edge a contact could be mistaken for.
    """

    t0: float  # time the penumbra's leading edge reaches x = 0
    speed_px_s: float = 2400.0  # 0.6 m/s walking, shadow at twice that, 2 px/mm
    penumbra_px: float = 600.0
    umbra_px: float = 800.0  # a 0.4 m wide body, doubled
    depth: float = 0.7  # share of the lamp's light the body blocks (the rest reaches the membrane off walls)

    def occlusion(self, t: float, width: int) -> np.ndarray | None:
        """Lamp-light loss per column (W,) float32 at ``t``, or None when the shadow is off the frame."""
        front = (t - self.t0) * self.speed_px_s  # x of the penumbra's leading edge
        total = 2 * self.penumbra_px + self.umbra_px
        if front <= 0.0 or front - total >= width:
            return None
        behind = front - np.arange(width, dtype=np.float32)  # how far the leading edge has passed each column
        rise = np.clip(behind / self.penumbra_px, 0.0, 1.0)
        fall = np.clip((total - behind) / self.penumbra_px, 0.0, 1.0)
        return (self.depth * np.minimum(rise, fall)).astype(np.float32)


@dataclass(frozen=True)
class RoomLight:
    """The room's own light through the membrane over time (see the module docstring)."""

    level: float = 0.0  # steady level before any step, fraction of the ROI's mean back-light
    steps: tuple[tuple[float, float, float], ...] = ()  # (start time, new level, ramp seconds), in time order
    drift_amp: float = 0.0  # daylight: relative amplitude of a slow sinusoid around the level
    drift_period_s: float = 20.0
    drift_phase: float = 0.0
    gradient: float = 0.15  # the lamp is off to one side: +- this across the ROI
    gradient_angle_deg: float = 0.0
    passer: Passer | None = None
    ae_tau_s: float = 0.3  # camera auto-exposure time constant (about 5 frames at 15 fps)
    # The shortest exposure the camera reaches, as a factor of the dim room's (0: no floor). 1.0 is a camera that
    # cannot shorten its exposure below the dim room's: the daemon locks the rear camera's exposure after its
    # settling period (feelium.cameras.picamera2_backend), so light that comes after the lock is not followed at all.
    ae_floor: float = 0.0

    def level_at(self, t: float) -> float:
        """Room light through the membrane at ``t`` (before any passer's shadow)."""
        level = self.level
        for start, new, ramp in self.steps:
            if t <= start:
                break
            share = 1.0 if ramp <= 0.0 else min(1.0, (t - start) / ramp)
            level = level + (new - level) * share
        if self.drift_amp:
            level *= 1.0 + self.drift_amp * math.sin(2.0 * math.pi * t / self.drift_period_s + self.drift_phase)
        return max(level, 0.0)

    def mean_at(self, t: float, width: int) -> float:
        """The level as the membrane's mean sees it (a passer's shadow included), what auto-exposure meters."""
        level = self.level_at(t)
        if self.passer is not None:
            loss = self.passer.occlusion(t, width)
            if loss is not None:
                level *= 1.0 - float(loss.mean())
        return level



class AutoExposure:
    """The camera's auto-exposure: ``1 / (1 + mean level)`` (never under ``ae_floor``) followed with the light's
    ``ae_tau_s`` lag.

    Stateful because a lag is: settled in the light of the first time asked
    (the camera has been running in it), then integrated exactly for
    piecewise-constant targets on a fine grid as time moves forward.
    """

    def __init__(self, light: RoomLight, width: int) -> None:
        self.light = light
        self.width = width
        self._t: float | None = None
        self._e = 1.0

    def _target(self, t: float) -> float:
        return max(1.0 / (1.0 + self.light.mean_at(t, self.width)), self.light.ae_floor)

    def at(self, t: float) -> float:
        """Exposure factor at ``t`` (times must not go backwards)."""
        if self._t is None or self.light.ae_tau_s <= 0.0:
            self._t, self._e = t, self._target(t)
            return self._e
        if t < self._t:
            raise ValueError(f"auto-exposure asked for {t} after {self._t}")
        k = 1.0 - math.exp(-AE_STEP_S / self.light.ae_tau_s)
        while self._t + AE_STEP_S <= t:
            self._t += AE_STEP_S
            self._e += (self._target(self._t) - self._e) * k
        return self._e


def lamp_image(
    backlight: np.ndarray, membrane: np.ndarray, roi: tuple[int, int, int, int], gradient: float, angle_deg: float
) -> np.ndarray:
    """Room light of level 1 on the camera (H, W) float32: the ROI's mean back-light, a gentle gradient, the membrane.

    ``membrane`` is the membrane's transmission: the room's light passes the same
    skin (weave, seams, the blackened envelope) as the projector's.
    """
    x, y, w, h = roi
    mean = float(backlight[y : y + h, x : x + w].mean())
    height, width = backlight.shape
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    a = math.radians(angle_deg)
    along = ((xx - (x + w / 2)) * math.cos(a) + (yy - (y + h / 2)) * math.sin(a)) / (max(w, h) / 2)
    profile = 1.0 + gradient * np.clip(along, -1.5, 1.5)
    return (mean * profile * membrane).astype(np.float32)
