"""The thermal scene renderer: a hand shows warm through the membrane and fades with distance."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.sim.thermal import ThermalSceneRenderer, WarmBody


def quiet(seed: int = 0, **kw) -> ThermalSceneRenderer:
    params = dict(noise_c=0.0, chess_c=0.0, fixed_pattern_c=0.0, drift_c=0.0)
    params.update(kw)
    return ThermalSceneRenderer(np.random.default_rng(seed), 22.0, **params)


def test_empty_scene_sits_at_ambient_with_noise():
    r = ThermalSceneRenderer(np.random.default_rng(1), 22.0, drift_c=0.0)
    f = r.frame(0.0, [])
    assert f.shape == (24, 32) and f.dtype == np.float32
    assert abs(float(f.mean()) - 22.0) < 0.1
    assert 0.05 < float(f.std()) < 0.3


def test_touching_hand_is_warm_at_its_position():
    f = quiet().frame(0.0, [WarmBody(u=0.25, v=0.5, distance_mm=0.0, radius=0.12)])
    row, col = np.unravel_index(np.argmax(f), f.shape)
    assert abs(col + 0.5 - 8) <= 1.5 and abs(row + 0.5 - 12) <= 1.5
    assert 6.0 < float(f.max()) - 22.0 < 11.0  # 11 degC skin rise times the membrane coupling
    assert float(f[2, 30]) == pytest.approx(22.0, abs=1e-3)


def test_hand_fades_and_spreads_with_distance():
    r = quiet()
    peaks, areas = [], []
    for d in (0.0, 100.0, 300.0, 600.0):
        f = r.frame(0.0, [WarmBody(0.5, 0.5, d, 0.12)]) - 22.0
        peaks.append(float(f.max()))
        areas.append(int((f > 0.5 * f.max()).sum()))
    assert peaks == sorted(peaks, reverse=True) and peaks[-1] > 0.5
    assert areas[0] > areas[-1]


def test_seeded_frames_repeat():
    bodies = [WarmBody(0.3, 0.6, 200.0, 0.2, 31.0)]
    a = ThermalSceneRenderer(np.random.default_rng(7)).frame(1.5, bodies)
    b = ThermalSceneRenderer(np.random.default_rng(7)).frame(1.5, bodies)
    assert np.array_equal(a, b)


def test_chess_pattern_flips_with_subpage():
    r = quiet(chess_c=0.1)
    a, b = r.frame(0.0, []), r.frame(1.0 / 8.0, [])
    assert np.allclose(a - b, np.where((np.add.outer(np.arange(24), np.arange(32)) % 2) == 0, 0.2, -0.2), atol=1e-5)


@given(
    u=st.floats(-0.5, 1.5), v=st.floats(-0.5, 1.5), d=st.floats(0, 5000), radius=st.floats(0, 1), skin=st.floats(20, 40),
    t=st.floats(0, 1e5),
)
def test_frames_are_finite_and_never_colder_than_the_room_plus_artefacts(u, v, d, radius, skin, t):
    f = quiet().frame(t, [WarmBody(u, v, d, radius, skin)])
    assert np.isfinite(f).all()
    assert float(f.max()) <= max(skin, 22.0) + 1e-3
