"""The simulator's projected-light physics the face-on measurement rests on (feelium.sim)."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.sim.projection import exposure_weights
from feelium.sim.scene import SceneRenderer, SceneState
from feelium.sim.sessions import session_presets


def test_exposure_weights_share_the_window_between_projector_frames() -> None:
    # 30 fps projector, 40 ms latency, 30 ms exposure centred on t = 0.1: in projector time [0.045, 0.075),
    # which straddles frame 1 [1/30, 2/30) and frame 2 [2/30, 3/30).
    weights = exposure_weights(0.1, 0.03, 30.0, 0.04)
    assert [k for k, _ in weights] == [1, 2]
    assert sum(w for _, w in weights) == pytest.approx(1.0)
    assert weights[0][1] == pytest.approx((2 / 30 - 0.045) / 0.03)
    assert exposure_weights(0.1, 0.0, 30.0, 0.0) == [(3, 1.0)]


def test_projected_light_scales_only_the_projectors_share() -> None:
    """With ``projected_share_only`` a black projection leaves the room light: s + (1 - s) * factor."""
    session = session_presets(1)["s1"]
    share_out = session.shadow.outside_share
    factor = np.full((480, 640), 0.2, np.float32)
    flat = SceneRenderer(session, np.random.default_rng(0)).signal(0.5, SceneState())
    lit = SceneRenderer(session, np.random.default_rng(0), projected=lambda t: factor, projected_share_only=True)
    ratio = lit.signal(0.5, SceneState()) / flat
    assert np.median(ratio) == pytest.approx(share_out + (1 - share_out) * 0.2, rel=1e-4)
    old = SceneRenderer(session, np.random.default_rng(0), projected=lambda t: factor).signal(0.5, SceneState()) / flat
    assert np.median(old) == pytest.approx(0.2, rel=1e-4)  # the default keeps the projector experiments' model
