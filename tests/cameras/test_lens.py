"""The lens model the headset gets: OpenCV's fisheye equations, and the simulator rendering exactly that lens."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from feelium.cameras.lens import FisheyeLens, LensError, load_lens, project, save_lens, unproject
from feelium.cameras.sim_front import PANORAMA_HEIGHT, PANORAMA_WIDTH, SimFisheyeRoom, sim_lens

LENS = FisheyeLens(640, 480, 205.0, 203.5, 322.2, 236.9, (0.031, -0.012, 0.004, -0.0007), "calibrated", 0.21)


def _points(n: int, max_theta_deg: float, seed: int = 4) -> np.ndarray:
    """Points in front of the camera up to ``max_theta_deg`` off axis, at 0.5-5 m."""
    rng = np.random.default_rng(seed)
    theta = np.radians(rng.uniform(0, max_theta_deg, n))
    phi = rng.uniform(-math.pi, math.pi, n)
    dist = rng.uniform(0.5, 5.0, n)
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1) * dist[:, None]


def test_project_is_opencvs_fisheye_projection():
    pts = _points(500, 89.0)
    ours = project(LENS, pts)
    theirs, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), LENS.K, LENS.D)
    assert np.abs(ours - theirs.reshape(-1, 2)).max() < 1e-9


def test_unproject_inverts_project_and_agrees_with_opencv():
    pts = _points(500, 89.0)
    dirs = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    back = unproject(LENS, project(LENS, pts))
    assert np.abs(back - dirs).max() < 1e-10
    near = pts[np.arccos(dirs[:, 2]) < math.radians(75)]  # OpenCV's own iteration gives up towards 90 degrees
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    normalised = cv2.fisheye.undistortPoints(project(LENS, near).reshape(-1, 1, 2), LENS.K, LENS.D, criteria=criteria)
    ours = unproject(LENS, project(LENS, near))
    assert np.abs(ours[:, :2] / ours[:, 2:] - normalised.reshape(-1, 2)).max() < 1e-6


def test_project_extends_past_90_degrees_where_opencv_cannot():
    lens = sim_lens(640, 480, fov_deg=220.0)
    side = project(lens, np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, -0.2]]))
    assert side[0] == pytest.approx([319.5 + lens.fx * math.pi / 2, 239.5])
    assert side[1] == pytest.approx([319.5, 239.5])
    assert side[2][1] < 239.5 - lens.fy * math.pi / 2  # behind the 90 degree circle, still above it
    assert np.abs(unproject(lens, side)[2] - np.array([0.0, -1.0, -0.2]) / math.hypot(1.0, 0.2)).max() < 1e-9


def _blobs(marks: list[tuple[float, float]]) -> np.ndarray:
    """A black panorama with a small Gaussian spot at each (azimuth, elevation), in the sim's panorama axes."""
    ys, xs = np.mgrid[0:PANORAMA_HEIGHT, 0:PANORAMA_WIDTH].astype(np.float64)
    pano = np.zeros((PANORAMA_HEIGHT, PANORAMA_WIDTH), np.float32)
    for az, el in marks:
        i = (az + math.pi) / (2 * math.pi) * PANORAMA_WIDTH
        j = (math.pi / 2 - el) / math.pi * PANORAMA_HEIGHT
        pano += np.exp(-((xs - i) ** 2 + (ys - j) ** 2) / (2 * 1.5**2)).astype(np.float32)
    return pano


def _centroid(image: np.ndarray, near: np.ndarray, half: int = 9) -> np.ndarray:
    x0, y0 = int(round(near[0])) - half, int(round(near[1])) - half
    window = image[y0 : y0 + 2 * half + 1, x0 : x0 + 2 * half + 1].astype(np.float64)
    ys, xs = np.mgrid[0 : window.shape[0], 0 : window.shape[1]]
    return np.array([(xs * window).sum() / window.sum() + x0, (ys * window).sum() / window.sum() + y0])


@pytest.mark.parametrize("size", [(640, 480), (320, 240)])
def test_the_served_sim_lens_is_the_lens_the_sim_renders(size):
    """Spots placed in the sim's room at known bearings are rendered where cv2.fisheye puts those directions."""
    width, height = size
    marks = [(math.radians(az), math.radians(el)) for az in (-75, -40, 0, 25, 60) for el in (-45, 0, 35)]
    view = SimFisheyeRoom(width, height).render(_blobs(marks))
    lens = sim_lens(width, height)
    dirs = np.array([[math.cos(el) * math.sin(az), -math.sin(el), math.cos(el) * math.cos(az)] for az, el in marks])
    expected, _ = cv2.fisheye.projectPoints(dirs.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), lens.K, lens.D)
    expected = expected.reshape(-1, 2)
    found = np.array([_centroid(view, p) for p in expected])
    assert np.abs(found - expected).max() < 0.1  # measured 0.04 px; a half-pixel convention slip gives 0.5


def test_scaling_keeps_the_lens_and_refuses_a_crop():
    big, small = sim_lens(1280, 960), sim_lens(640, 480)
    scaled = big.scaled(640, 480)
    for name in ("fx", "fy", "cx", "cy"):
        assert getattr(scaled, name) == pytest.approx(getattr(small, name))
    assert scaled.d == big.d
    with pytest.raises(LensError, match="aspect"):
        big.scaled(640, 360)


def test_json_round_trip_and_file(tmp_path):
    data = LENS.to_json()
    assert json.loads(json.dumps(data)) == data
    assert data["K"] == [[205.0, 0.0, 322.2], [0.0, 203.5, 236.9], [0.0, 0.0, 1.0]] and data["D"] == list(LENS.d)
    assert FisheyeLens.from_json(data) == LENS
    path = save_lens(LENS, tmp_path / "sub" / "front_lens.json")
    assert load_lens(path) == LENS


@pytest.mark.parametrize(
    "change, message",
    [
        ({"model": "pinhole"}, "opencv_fisheye"),
        ({"D": [0.1, 0.2]}, "4 coefficients"),
        ({"K": [[200, 1, 320], [0, 200, 240], [0, 0, 1]]}, "no skew"),
        ({"K": [[-200, 0, 320], [0, 200, 240], [0, 0, 1]]}, "positive"),
        ({"width": "wide"}, "not a number"),
        ({"source": "guess"}, "source"),
    ],
)
def test_bad_lens_json_is_refused_with_a_reason(change, message):
    with pytest.raises(LensError, match=message):
        FisheyeLens.from_json(LENS.to_json() | change)


def test_an_unreadable_lens_file_names_itself(tmp_path):
    bad = tmp_path / "lens.json"
    bad.write_text("{", encoding="utf-8")
    with pytest.raises(LensError, match="lens.json"):
        load_lens(bad)
