"""The whole front face's geometry: camera pixel <-> skin u, v on the envelope, local scale, JSON."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.skin.face import FaceModel

FACE = FaceModel.for_frame(640, 480)
unit = st.floats(0.0, 1.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(u=unit, v=unit, behind=st.floats(0.0, 300.0))
def test_u_v_to_camera_and_back_is_the_identity(u, v, behind):
    face = FaceModel.for_frame(640, 480, camera_behind_mm=behind)
    x, y = face.to_camera(u, v)
    assert 0.0 <= x < 640 and 0.0 <= y < 480  # the whole face is on the frame
    back = face.to_uv(x, y)
    assert float(back[0]) == pytest.approx(u, abs=1e-9) and float(back[1]) == pytest.approx(v, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(x=st.floats(0.0, 639.0), y=st.floats(0.0, 479.0))
def test_camera_to_u_v_and_back_is_the_identity(x, y):
    u, v = FACE.to_uv(x, y)
    assert np.isfinite(u) and np.isfinite(v)  # the camera is inside: every ray meets the envelope
    bx, by = FACE.to_camera(u, v)
    assert float(bx) == pytest.approx(x, abs=1e-6) and float(by) == pytest.approx(y, abs=1e-6)


@settings(max_examples=100, deadline=None)
@given(u=unit, v=unit)
def test_from_the_centre_the_face_is_the_browser_clients_direction_through_an_equidistant_lens(u, v):
    """docs/api.md: azimuth (u - 0.5) * 100, elevation (0.5 - v) * 75, direction (sin az cos el, -sin el, cos az cos el)."""
    face = FaceModel(640, 480, focal_px=300.0, cx=319.5, cy=239.5, camera_behind_mm=0.0)
    az, el = math.radians((u - 0.5) * 100), math.radians((0.5 - v) * 75)
    d = np.array([math.sin(az) * math.cos(el), -math.sin(el), math.cos(az) * math.cos(el)])
    theta = math.acos(d[2])
    rho = math.hypot(d[0], d[1])
    k = theta / rho if rho > 1e-12 else 1.0
    x, y = face.to_camera(u, v)
    assert float(x) == pytest.approx(319.5 + 300.0 * k * d[0], abs=1e-6)
    assert float(y) == pytest.approx(239.5 + 300.0 * k * d[1], abs=1e-6)


def test_axes_u_to_the_right_v_down_as_the_camera_sees_it():
    x, y = FACE.to_camera(0.5, 0.5)
    assert (float(x), float(y)) == pytest.approx((FACE.cx, FACE.cy))
    xr, _ = FACE.to_camera(0.8, 0.5)
    _, yd = FACE.to_camera(0.5, 0.8)
    assert xr > FACE.cx and yd > FACE.cy


def test_scale_on_the_axis_is_focal_over_distance_and_grows_at_most_a_quarter_at_the_rim():
    centre = float(FACE.px_per_mm(0.5, 0.5))
    assert centre == pytest.approx(FACE.focal_px / (FACE.radius_mm + FACE.camera_behind_mm), rel=1e-4)
    u, v = np.meshgrid(np.linspace(0, 1, 21), np.linspace(0, 1, 21))
    ratio = FACE.px_per_mm(u, v) / centre
    assert ratio.min() >= 0.99 and ratio.max() < 1.25


def test_mask_and_roi_hold_the_face_and_nothing_else():
    mask = FACE.mask()
    x, y, w, h = FACE.roi()
    assert mask[y : y + h, x : x + w].sum() == mask.sum()
    u, v = FACE.to_uv(*np.meshgrid(np.arange(640.0), np.arange(480.0)))
    assert np.all((u[mask] >= 0) & (u[mask] < 1) & (v[mask] >= 0) & (v[mask] < 1))
    assert not mask[y, x] and not mask[y + h - 1, x + w - 1]  # the box's corners are the black envelope


def test_json_round_trip_and_errors_name_the_field():
    assert FaceModel.from_json(FACE.to_json()) == FACE
    obj = FACE.to_json()
    with pytest.raises(ValueError, match="focal_px"):
        FaceModel.from_json({**obj, "focal_px": "wide"})
    with pytest.raises(ValueError, match="unknown key 'lens'"):
        FaceModel.from_json({**obj, "lens": 1})
    with pytest.raises(ValueError, match="missing 'cx'"):
        FaceModel.from_json({k: val for k, val in obj.items() if k != "cx"})
    with pytest.raises(ValueError, match="camera_behind_mm"):
        FaceModel.from_json({**obj, "camera_behind_mm": 400.0})


def test_distance_on_the_membrane_is_the_arc_of_the_azimuth_on_the_equator():
    assert float(FACE.distance_mm(0.5, 0.5, 0.8, 0.5)) == pytest.approx(320.0 * math.radians(30.0))
    assert float(FACE.distance_mm(0.3, 0.2, 0.3, 0.2)) == pytest.approx(0.0, abs=1e-9)


def test_the_mask_is_read_only_and_computed_once():
    assert FACE.mask() is FACE.mask()
    with pytest.raises(ValueError):
        FACE.mask()[0, 0] = True
