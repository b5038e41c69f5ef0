"""The scene model's parts: back-light, membrane, shadows by height, hand, contact patch."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.sim.hand import HandPose, hand_parts
from feelium.sim.optics import OpticsParams, backlight, laser_banding, membrane_transmission, roi_ratio
from feelium.sim.sessions import session_presets
from feelium.sim.scene import ROI, SceneRenderer, SceneState
from feelium.sim.shadow import Capsule, Ellipse, ShadowParams, render_shadow

W, H = 640, 480


@pytest.mark.parametrize("name", ["s1", "s2", "s3"])
def test_backlight_is_uneven_at_least_three_to_one(name: str) -> None:
    session = session_presets(7)[name]
    b = backlight(session.optics, W, H, ROI)
    assert roi_ratio(b, ROI) >= 3.0
    x, y, w, h = ROI
    assert b[y : y + h, x : x + w].max() == pytest.approx(session.optics.level, rel=1e-4)


def test_sessions_differ_in_lighting_noise_and_projector() -> None:
    s = session_presets(1)
    assert len({v.optics.level for v in s.values()}) == 3
    assert len({v.sensor.read_dn for v in s.values()}) == 3
    assert len({v.optics.banding_amp for v in s.values()}) == 3


def test_envelope_outside_roi_is_near_black_and_patch_is_textured() -> None:
    p = OpticsParams()
    t = membrane_transmission(p, W, H, ROI, np.random.default_rng(0))
    x, y, w, h = ROI
    assert t[: y - 4].max() < 0.05 and t[:, : x - 4].max() < 0.05
    inner = t[y + 10 : y + h - 10, x + 10 : x + w - 10]
    assert 0.02 < inner.std() < 0.15  # texture and seams, but not a different material
    assert inner.min() < 0.85  # a seam crosses the patch


def test_laser_banding_is_a_faint_moving_stripe() -> None:
    p = OpticsParams(banding_amp=0.04)
    a, b = laser_banding(p, H, 0.0), laser_banding(p, H, 0.3)
    assert a.shape == (H, 1)
    assert a.max() == pytest.approx(1.04, abs=1e-3) and a.min() == pytest.approx(0.96, abs=1e-3)
    assert not np.allclose(a, b)


def _peak(height_mm: float, radius_px: float = 10.0) -> float:
    params = ShadowParams(fill_mm=1e9)  # geometry only
    shadow = render_shadow([Ellipse(320, 240, radius_px, radius_px, 0, height_mm)], [], params, W, H)
    return float(shadow.occlusion.max())


def _edge_width(height_mm: float) -> float:
    """10-90 % width of the shadow edge of a large part, in px."""
    params = ShadowParams(fill_mm=1e9)
    shadow = render_shadow([Ellipse(320, 240, 150, 150, 0, height_mm)], [], params, W, H)
    profile = shadow.occlusion[240, 320:]
    top = profile[0]
    x10 = int(np.argmax(profile < 0.1 * top))
    x90 = int(np.argmax(profile < 0.9 * top))
    return float(x10 - x90)


@settings(max_examples=25, deadline=None)
@given(st.floats(0.0, 60.0), st.floats(0.5, 40.0))
def test_shadow_depth_fades_with_height(h: float, dh: float) -> None:
    assert _peak(h + dh) <= _peak(h) + 1e-3


def test_shadow_blur_grows_about_linearly_with_height() -> None:
    widths = [_edge_width(h) for h in (0.0, 10.0, 20.0, 40.0)]
    assert widths == sorted(widths) and widths[0] < 4.0
    params = ShadowParams()
    expected = 2.563 * params.spread_per_mm * params.px_per_mm * 30.0  # 10-90 % of a Gaussian edge is 2.563 sigma
    assert widths[3] - widths[1] == pytest.approx(expected, rel=0.2)


def test_close_hover_darkens_almost_like_a_touch_but_only_touch_gets_the_core() -> None:
    params = ShadowParams()
    touch = hand_parts(HandPose(320, 240, 0.0), params.px_per_mm)
    hover = hand_parts(HandPose(320, 240, 3.0), params.px_per_mm)
    assert len(touch[1]) == 1 and hover[1] == []
    s_touch = render_shadow(*touch, params, W, H).transmission(params)
    s_hover = render_shadow(*hover, params, W, H).transmission(params)
    d_touch, d_hover = 1 - s_touch[240, 320], 1 - s_hover[240, 320]
    assert d_touch > d_hover > 0.6 * params.outside_share
    far = render_shadow(*hand_parts(HandPose(320, 240, 30.0), params.px_per_mm), params, W, H).transmission(params)
    assert far[240, 320] > 1 - 0.5 * d_hover


def test_contact_patch_is_a_fingertip_sized_sharp_ellipse() -> None:
    params = ShadowParams()
    parts, contacts = hand_parts(HandPose(320, 240, 0.0, heading=0.0), params.px_per_mm)
    patch = contacts[0]
    assert 8.0 <= max(patch.ax, patch.ay) <= 14.0 and 8.0 <= min(patch.ax, patch.ay) + 1.0
    shadow = render_shadow([], contacts, params, W, H)
    row = shadow.contact[240]
    assert row[320] > 0.95 and row[320 + 16] < 0.05  # sharp: gone 4 px beyond the edge


def test_finger_rises_from_the_tip() -> None:
    parts, _ = hand_parts(HandPose(320, 240, 0.0, pitch_deg=40), 2.0)
    finger = [p for p in parts if isinstance(p, Capsule)][:5]
    heights = [p.height_mm for p in finger]
    assert heights == sorted(heights) and heights[0] < 5.0 and heights[-1] > 30.0


def test_room_light_step_changes_only_the_outside_share() -> None:
    session = session_presets(1)["s1"]
    r = SceneRenderer(session, np.random.default_rng(0))
    lit = r.signal(1.0, SceneState())
    dark = r.signal(1.0, SceneState(room=0.0))
    ratio = dark[ROI[1] : ROI[1] + ROI[3], ROI[0] : ROI[0] + ROI[2]] / lit[ROI[1] : ROI[1] + ROI[3], ROI[0] : ROI[0] + ROI[2]]
    assert np.allclose(ratio, 1.0 - session.shadow.outside_share, atol=1e-4)


def test_projected_hook_multiplies_the_backlight() -> None:
    session = session_presets(1)["s1"]
    factor = np.ones((H, W), np.float32)
    factor[:, :320] = 0.5
    plain = SceneRenderer(session, np.random.default_rng(0)).signal(0.5, SceneState())
    hooked = SceneRenderer(session, np.random.default_rng(0), projected=lambda t: factor).signal(0.5, SceneState())
    assert np.allclose(hooked[:, :320], 0.5 * plain[:, :320]) and np.allclose(hooked[:, 320:], plain[:, 320:])
    none_hook = SceneRenderer(session, np.random.default_rng(0), projected=lambda t: None).signal(0.5, SceneState())
    assert np.allclose(none_hook, plain)
    bad = SceneRenderer(session, np.random.default_rng(0), projected=lambda t: np.ones((10, 10), np.float32))
    with pytest.raises(ValueError, match="projected factor"):
        bad.signal(0.5, SceneState())


def test_fast_moving_hand_is_smeared_over_the_exposure_still_hand_is_not() -> None:
    from feelium.sim.scene import exposure_samples

    def moving(t: float) -> SceneState:
        return SceneState(hands=(HandPose(200 + 600 * t, 240, 0.0),))  # 600 px/s: 18 px in 30 ms

    def still(t: float) -> SceneState:
        return SceneState(hands=(HandPose(320, 240, 0.0),))

    assert len(exposure_samples(still, 0.2, 0.03)) == 1
    samples = exposure_samples(moving, 0.2, 0.03)
    assert len(samples) == 4 and samples[0].hands[0].x < 320 < samples[-1].hands[0].x
    session = session_presets(1)["s1"]
    r = SceneRenderer(session, np.random.default_rng(0))
    sharp, blurred = r.signal(0.2, moving(0.2)), r.signal(0.2, samples)
    ref = r.signal(0.2, SceneState())
    row_sharp, row_blur = 1 - sharp[240] / ref[240], 1 - blurred[240] / ref[240]
    assert row_blur.max() < row_sharp.max()  # the core is shallower...
    assert (row_blur > 0.3).sum() > (row_sharp > 0.3).sum()  # ...and longer along the motion
