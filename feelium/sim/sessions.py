"""The three simulated sessions (lighting, noise, projector), shared by the live scene and dataset generation.

Both the daemon's simulated rear camera and the paper-protocol generator draw
their scene from these presets, so a live simulated blimp looks like the
recordings the touch thresholds were measured on.
"""

from __future__ import annotations

import numpy as np

from feelium.sim.camera import SensorParams
from feelium.sim.optics import OpticsParams
from feelium.sim.scene import Session
from feelium.sim.shadow import ShadowParams

SESSION_NAMES = ("s1", "s2", "s3")


def session_presets(seed: int) -> dict[str, Session]:
    """Three sessions that differ in lighting, noise and projector (placements drawn from ``seed``).

    s1: dim room, bright projector, clean sensor. s2: dimmer projector with
    steeper falloff, noisier sensor, stronger faster banding, more drops.
    s3: more room light from a narrower direction, a hot spot that clips.
    """
    rng = np.random.default_rng([seed, 0x5E55])

    def placement() -> dict[str, float]:
        return {
            "center_dx": float(rng.uniform(-25, 25)),
            "center_dy": float(rng.uniform(-20, 20)),
            "hotspot_dx": float(rng.uniform(-80, 80)),
            "hotspot_dy": float(rng.uniform(-60, 60)),
        }

    s1 = Session(
        "s1",
        OpticsParams(level=185.0, throw_px=330.0, hotspot_gain=0.35, banding_amp=0.03, **placement()),
        ShadowParams(outside_share=0.55, spread_per_mm=0.6, contact_depth=0.45),
        SensorParams(gain=1.0, shot_dn=0.35, read_dn=1.8, drift_amp=0.025, jitter_ms=3.0, drop_rate=0.01),
        ambient_c=22.0,
    )
    s2 = Session(
        "s2",
        OpticsParams(
            level=125.0, throw_px=290.0, hotspot_gain=0.25, hotspot_sigma=90.0, banding_amp=0.05,
            banding_period_px=29.0, banding_speed_hz=1.3, **placement(),
        ),
        ShadowParams(outside_share=0.5, spread_per_mm=0.7, contact_depth=0.4),
        SensorParams(gain=1.0, shot_dn=0.6, read_dn=2.6, drift_amp=0.035, jitter_ms=5.0, drop_rate=0.025),
        ambient_c=20.5,
    )  # fmt: skip
    s3 = Session(
        "s3",
        OpticsParams(
            level=238.0, throw_px=360.0, hotspot_gain=0.5, hotspot_sigma=55.0, banding_amp=0.02,
            banding_period_px=45.0, banding_speed_hz=0.4, **placement(),
        ),
        ShadowParams(outside_share=0.62, spread_per_mm=0.45, contact_depth=0.5),
        SensorParams(gain=1.04, shot_dn=0.3, read_dn=1.5, drift_amp=0.02, jitter_ms=2.0, drop_rate=0.008),
        ambient_c=24.5,
    )  # fmt: skip
    return {s.name: s for s in (s1, s2, s3)}
