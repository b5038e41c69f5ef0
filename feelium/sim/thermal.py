"""What the MLX90640 inside the blimp sees: warm bodies through the membrane, as object temperatures.

The thermal camera sits inside the envelope looking out through the back-lit
skin. A hand pressed on the skin warms it and shows as a small, sharp warm
spot; the same hand further out shows through the thin film as a weaker,
smaller, blurrier blob (the film transmits part of the infrared and scatters
it). The renderer produces the (24, 32) degC frame the sensor's decoder would
output, with the sensor's own artefacts (per-pixel noise, the chess pattern
between its two sub-pages, a fixed pixel offset pattern) and the room's slow
ambient drift, so the presence detector is tested against what it will meet.

Pure: time is an input and all randomness comes from the generator passed in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

ROWS, COLS = 24, 32


@dataclass(frozen=True)
class WarmBody:
    """A warm body outside the membrane.

    ``u``, ``v``: position across the sensor's columns and rows (0..1, row 0
    at the top); ``radius``: its radius as a fraction of the sensor's width
    when touching the membrane; ``distance_mm``: its distance from the
    membrane (0 = touching); ``skin_c``: its surface temperature.
    """

    u: float
    v: float
    distance_mm: float
    radius: float
    skin_c: float = 33.0


class ThermalSceneRenderer:
    """Renders (24, 32) float32 degC frames of warm bodies seen through the membrane.

    ``sensor_to_membrane_mm``: how far the sensor sits behind the skin (sets
    how fast a body shrinks with distance). ``transmission``: the share of a
    distant body's temperature rise that passes through the film;
    ``contact_gain``: the extra rise from conduction when it touches, which
    fades over ``contact_mm``. ``blur_px``/``blur_px_per_m``: the film's
    scattering blur at contact and its growth with distance. ``noise_c``:
    per-pixel temporal noise (1 sigma); ``chess_c``: amplitude of the
    checkerboard offset that flips sign with the sub-page; ``fixed_pattern_c``:
    sigma of a static per-pixel offset; ``drift_c``/``drift_period_s``: the
    slow sinusoidal drift of the ambient temperature; ``fps``: the full-frame
    rate (sets which sub-page was read last).
    """

    def __init__(
        self,
        rng: np.random.Generator,
        ambient_c: float = 22.0,
        *,
        sensor_to_membrane_mm: float = 300.0,
        transmission: float = 0.45,
        contact_gain: float = 0.35,
        contact_mm: float = 15.0,
        blur_px: float = 0.8,
        blur_px_per_m: float = 2.5,
        noise_c: float = 0.12,
        chess_c: float = 0.05,
        fixed_pattern_c: float = 0.08,
        drift_c: float = 0.4,
        drift_period_s: float = 600.0,
        fps: float = 4.0,
    ) -> None:
        if not math.isfinite(ambient_c):
            raise ValueError(f"ambient_c must be finite, got {ambient_c!r}")
        if sensor_to_membrane_mm <= 0:
            raise ValueError(f"sensor_to_membrane_mm must be positive, got {sensor_to_membrane_mm!r}")
        if fps <= 0:
            raise ValueError(f"fps must be positive, got {fps!r}")
        self.rng = rng
        self.ambient_c = float(ambient_c)
        self.sensor_to_membrane_mm = float(sensor_to_membrane_mm)
        self.transmission = float(transmission)
        self.contact_gain = float(contact_gain)
        self.contact_mm = float(contact_mm)
        self.blur_px = float(blur_px)
        self.blur_px_per_m = float(blur_px_per_m)
        self.noise_c = float(noise_c)
        self.chess_c = float(chess_c)
        self.drift_c = float(drift_c)
        self.drift_period_s = float(drift_period_s)
        self.fps = float(fps)
        self._drift_phase = float(rng.uniform(0.0, 2.0 * math.pi))
        self._fixed = (rng.standard_normal((ROWS, COLS)) * fixed_pattern_c).astype(np.float32)
        rows, cols = np.mgrid[0:ROWS, 0:COLS]
        self._checker = np.where((rows + cols) % 2 == 0, 1.0, -1.0).astype(np.float32)
        # pixel centres in sensor pixels
        self._x = cols.astype(np.float64) + 0.5
        self._y = rows.astype(np.float64) + 0.5

    def ambient_at(self, t: float) -> float:
        """The room temperature the membrane and background sit at, at time ``t``."""
        if self.drift_period_s <= 0:
            return self.ambient_c
        return self.ambient_c + self.drift_c * math.sin(2.0 * math.pi * t / self.drift_period_s + self._drift_phase)

    def body_rise(self, body: WarmBody, ambient: float) -> np.ndarray:
        """The temperature rise one body adds to each pixel (no noise), in degC."""
        d = max(0.0, float(body.distance_mm))
        scale = self.sensor_to_membrane_mm / (self.sensor_to_membrane_mm + d)
        radius_px = max(0.0, float(body.radius)) * COLS * scale
        sigma = self.blur_px + self.blur_px_per_m * d / 1000.0
        coupling = self.transmission + self.contact_gain * math.exp(-d / self.contact_mm) if self.contact_mm > 0 else self.transmission
        amplitude = (float(body.skin_c) - ambient) * coupling
        cx, cy = float(body.u) * COLS, float(body.v) * ROWS
        r = np.hypot(self._x - cx, self._y - cy)
        # a disc convolved with a Gaussian, by the radial error-function approximation
        # (exact in 1-D, close in 2-D for sigma below the radius; smooth to a spot for small discs)
        if radius_px <= 1e-6:
            return np.zeros((ROWS, COLS))
        s = max(sigma, 1e-3) * math.sqrt(2.0)
        edge = 0.5 * (_erf((radius_px - r) / s) + _erf((radius_px + r) / s))
        # a disc narrower than the blur spreads its heat over the blur: the peak falls
        peak_factor = 1.0 - math.exp(-(radius_px**2) / (2.0 * max(sigma, 1e-3) ** 2))
        peak_edge = float(_erf(radius_px / s))
        if peak_edge > 0:
            edge = edge / peak_edge * peak_factor
        return amplitude * edge

    def frame(self, t: float, bodies: Sequence[WarmBody]) -> np.ndarray:
        """The (24, 32) float32 degC frame the decoder would output at time ``t``."""
        ambient = self.ambient_at(t)
        scene = np.full((ROWS, COLS), ambient, dtype=np.float64)
        for body in bodies:
            scene = np.maximum(scene, ambient + self.body_rise(body, ambient))
        subpage_sign = 1.0 if int(math.floor(t * self.fps * 2.0)) % 2 == 0 else -1.0
        scene += self._fixed + self.chess_c * subpage_sign * self._checker
        scene += self.rng.standard_normal((ROWS, COLS)) * self.noise_c
        return scene.astype(np.float32)


def _erf(x: np.ndarray | float) -> np.ndarray:
    """Vectorised error function (Abramowitz-Stegun 7.1.26, |error| < 1.5e-7): numpy has none."""
    x = np.asarray(x, dtype=np.float64)
    sign = np.sign(x)
    a = np.abs(x)
    k = 1.0 / (1.0 + 0.3275911 * a)
    poly = k * (0.254829592 + k * (-0.284496736 + k * (1.421413741 + k * (-1.453152027 + k * 1.061405429))))
    return sign * (1.0 - poly * np.exp(-a * a))





@dataclass(frozen=True)
class Visit:
    """One body walking in from ``far_mm``, staying at ``near_mm``, and walking out again.

    Times in seconds: it starts moving at ``t_start``, arrives after
    ``walk_s``, stays ``stay_s``, and takes ``walk_s`` to leave.
    """

    t_start: float
    walk_s: float
    stay_s: float
    u: float
    v: float
    radius: float
    skin_c: float = 33.0
    far_mm: float = 2000.0
    near_mm: float = 0.0

    @property
    def t_end(self) -> float:
        return self.t_start + 2 * self.walk_s + self.stay_s

    def distance(self, t: float) -> float | None:
        """Distance from the membrane at ``t``; ``None`` before it starts or after it has gone."""
        if t < self.t_start or t > self.t_end:
            return None
        walk = max(self.walk_s, 1e-9)
        if t < self.t_start + self.walk_s:
            f = (t - self.t_start) / walk
        elif t <= self.t_start + self.walk_s + self.stay_s:
            f = 1.0
        else:
            f = 1.0 - (t - self.t_start - self.walk_s - self.stay_s) / walk
        return self.far_mm + (self.near_mm - self.far_mm) * f

    def body(self, t: float) -> WarmBody | None:
        d = self.distance(t)
        return None if d is None else WarmBody(self.u, self.v, d, self.radius, self.skin_c)

    def near_interval(self, near_mm: float) -> tuple[float, float] | None:
        """When the body is within ``near_mm`` of the membrane (linear walk), or ``None`` if never."""
        if self.near_mm >= near_mm:
            return None
        f = (self.far_mm - near_mm) / (self.far_mm - self.near_mm) if self.far_mm > self.near_mm else 0.0
        return self.t_start + f * self.walk_s, self.t_end - f * self.walk_s


def demo_visits(period_s: float = 40.0) -> tuple[Visit, ...]:
    """One cycle of the simulator's default thermal scene: a partner walks up and touches, then leaves."""
    return (
        Visit(t_start=5.0, walk_s=4.0, stay_s=6.0, u=0.45, v=0.55, radius=0.45, skin_c=30.0, near_mm=250.0),
        Visit(t_start=8.0, walk_s=1.0, stay_s=3.0, u=0.6, v=0.4, radius=0.12, skin_c=33.0, far_mm=400.0),
    )


def demo_bodies(t: float, period_s: float = 40.0) -> list[WarmBody]:
    """The warm bodies of the repeating demo scene at ``t`` (every ``period_s`` seconds a visit)."""
    phase = t % period_s
    return [b for b in (v.body(phase) for v in demo_visits(period_s)) if b is not None]
__all__ = ["COLS", "ROWS", "ThermalSceneRenderer", "Visit", "WarmBody", "demo_bodies", "demo_visits"]
