"""The rear camera as a sensor: gain drift, shot and read noise, 8-bit clipping, timing.

A pixel collects photo-electrons (Poisson: variance equals the mean), the
readout adds Gaussian read noise, the ADC scales by the conversion gain and
clips to 8 bits. In DN that is variance ``shot_dn * value + read_dn^2`` around
``value``; at these signal levels (tens of electrons per DN step and up) the
Gaussian approximation of the Poisson law is exact enough and much faster.

Frame times come from the sensor's own clock: a nominal period, a few ms of
jitter (scheduling on a busy Pi) and now and then a dropped frame (the slot
passes with no frame), as a real capture shows.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class SensorParams:
    """One session's camera."""

    fps: float = 15.0
    exposure_s: float = 0.03  # shutter time: a dim membrane needs about half the frame period
    gain: float = 1.0  # overall exposure gain (DN per unit back-light)
    drift_amp: float = 0.025  # slow gain drift amplitude, relative (sensor temperature, projector power)
    drift_period_s: float = 41.0
    shot_dn: float = 0.35  # shot noise variance per DN of signal (1 / electrons per DN)
    read_dn: float = 1.8  # read noise standard deviation in DN
    jitter_ms: float = 3.0  # timestamp jitter (standard deviation)
    drop_rate: float = 0.012  # probability that a frame slot is dropped

    def to_json(self) -> dict[str, float]:
        return asdict(self)


def frame_times(params: SensorParams, duration_s: float, rng: np.random.Generator, start_s: float = 0.0) -> np.ndarray:
    """Capture times over ``[start_s, start_s + duration_s)`` with jitter and drops; strictly increasing."""
    period = 1.0 / params.fps
    slots = start_s + np.arange(int(math.floor(duration_s * params.fps)), dtype=np.float64) * period
    jitter = np.clip(rng.normal(0.0, params.jitter_ms * 1e-3, len(slots)), -0.3 * period, 0.3 * period)
    keep = rng.random(len(slots)) >= params.drop_rate
    if len(keep):
        keep[0] = True  # a recording starts with a frame near its clock's zero
    times = np.maximum(slots + jitter, 0.0)[keep]
    return times


def gain_at(params: SensorParams, t: float, phase: float) -> float:
    """Exposure gain at time ``t``: slow drift from two incommensurate periods."""
    w = 2.0 * math.pi / params.drift_period_s
    drift = 0.7 * math.sin(w * t + phase) + 0.3 * math.sin(2.71 * w * t + 2.0 * phase)
    return params.gain * (1.0 + params.drift_amp * drift)


def expose(signal: np.ndarray, params: SensorParams, rng: np.random.Generator) -> np.ndarray:
    """Digitise a noiseless signal (DN, float32): add shot and read noise, round, clip to 8 bits."""
    sigma = np.sqrt(np.maximum(signal, 0.0) * params.shot_dn + params.read_dn**2, dtype=np.float32)
    noisy = signal + sigma * rng.standard_normal(signal.shape, dtype=np.float32)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
