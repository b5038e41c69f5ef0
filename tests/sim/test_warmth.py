"""The thermal channel's mapping from the scene to warm bodies."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.sim.hand import Blob, HandPose
from feelium.sim.scene import ROI, SceneState
from feelium.sim.warmth import hand_bodies, thermal_times, warm_bodies


def test_fingertip_maps_to_the_patch_coordinates() -> None:
    tip, palm = hand_bodies(HandPose(64 + 256, 48 + 96, 0.0), ROI, 2.0)
    assert (tip.u, tip.v, tip.distance_mm) == pytest.approx((0.5, 0.25, 0.0))
    assert tip.radius == pytest.approx(8.0 / 256.0)
    assert palm.v > tip.v and palm.distance_mm > 40.0 and palm.radius > tip.radius  # arm comes from below


def test_bodies_and_hands_all_become_warm_bodies() -> None:
    state = SceneState(hands=(HandPose(300, 200, 5.0),), blobs=(Blob(320, 240, 150, 200, 300.0),))
    bodies = warm_bodies(state, ROI, 2.0)
    assert len(bodies) == 3 and bodies[-1].distance_mm == 300.0 and bodies[-1].skin_c < 33.0


def test_thermal_times_are_8_hz_and_increasing() -> None:
    t = thermal_times(10.0, np.random.default_rng(0))
    assert np.all(np.diff(t) > 0) and len(t) in (79, 80) and np.median(np.diff(t)) == pytest.approx(0.125, abs=2e-3)
