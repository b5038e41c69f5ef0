"""Chessboard and ChArUco views rendered through a known fisheye lens: ground truth for ``feelium calibrate lens``.

Each view is ray-traced (every pixel's direction from :func:`feelium.cameras.lens.unproject`, met with the
board's plane), at twice the resolution and then averaged down, so corners are anti-aliased like a real
camera's and the calibration can be held to the lens that made them.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from feelium.cameras.lens import FisheyeLens, project, unproject
from feelium.lab.lens.calibrate import Board, CharucoBoard, Target

SUPERSAMPLE = 2
# A wide lens a little different from equidistant (what a cheap 180-200 degree M12 fisheye looks like).
TRUTH = FisheyeLens(640, 480, 198.0, 197.2, 323.4, 236.1, (0.021, -0.0135, 0.0042, -0.0011), "calibrated")


def _rotation(rx: float, ry: float, rz: float) -> np.ndarray:
    return cv2.Rodrigues(np.array([rx, ry, rz], dtype=np.float64))[0]


def board_poses(
    lens: FisheyeLens, board: Target, n: int, rng: np.random.Generator, margin_px: float = 12.0,
    min_inside: float = 1.0, max_off_axis_deg: float = 70.0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` poses ``(R, t)`` (board to camera) with at least ``min_inside`` of the board's corners inside the
    image, spread from the centre to ``max_off_axis_deg`` (the edge is where a fisheye's distortion is
    measured; a ChArUco board may hang over it)."""
    obj = board.object_points()
    centre = obj.mean(axis=0)
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    while len(poses) < n:
        k = len(poses)
        off_axis = math.radians(max_off_axis_deg) * math.sqrt((k + 0.5) / n)  # even coverage of the image disc
        around = rng.uniform(-math.pi, math.pi)
        distance = rng.uniform(0.22, 0.4)
        direction = np.array([math.sin(off_axis) * math.cos(around), math.sin(off_axis) * math.sin(around), math.cos(off_axis)])
        # face the camera roughly, then tilt by up to 35 degrees and spin freely
        facing = _rotation(0.0, 0.0, rng.uniform(-math.pi, math.pi))
        tilt = _rotation(rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), 0.0)
        towards = _rotation(*(np.cross([0.0, 0.0, 1.0], direction) / max(np.linalg.norm(np.cross([0.0, 0.0, 1.0], direction)), 1e-9) * off_axis * 0.5))
        r = towards @ tilt @ facing
        t = direction * distance - r @ centre
        corners = (r @ obj.T).T + t
        if np.any(corners[:, 2] <= 0.02):
            continue
        px = project(lens, corners)
        inside = np.all((px >= margin_px) & (px <= np.array([lens.width, lens.height]) - 1 - margin_px), axis=1)
        if inside.mean() >= min_inside:
            poses.append((r, t))
    return poses


def _board_plane(pose: tuple[np.ndarray, np.ndarray], rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each ray meets the board's plane: (distance along the ray, board coordinates in metres)."""
    r, t = pose
    normal = r[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = (normal @ t) / (rays @ normal)
    hit = rays * reach[..., None] - t
    return reach, hit @ r  # R^T (point - t), row-wise


def _camera_image(lens: FisheyeLens, image: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """Averaged down from the supersampled render (anti-aliased edges, as a lens gives), with sensor noise."""
    small = cv2.resize(image.astype(np.float32), (lens.width, lens.height), interpolation=cv2.INTER_AREA)
    small += rng.normal(0.0, noise, small.shape).astype(np.float32)
    return np.clip(small, 0, 255).astype(np.uint8)


def render_charuco(lens: FisheyeLens, board: CharucoBoard, pose: tuple[np.ndarray, np.ndarray], rays: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """The gray view of a ChArUco board: OpenCV's own printout of it (40 px a square), mapped onto its plane."""
    px_per_m = 40.0 / board.square_m
    margin_px = 20
    texture = board.opencv.generateImage((board.cols * 40 + 2 * margin_px, board.rows * 40 + 2 * margin_px), marginSize=margin_px)
    texture = np.where(texture > 127, 225, 25).astype(np.float32)  # printed black and white under room light
    reach, local = _board_plane(pose, rays)
    map_x = (local[..., 0] * px_per_m + margin_px - 0.5).astype(np.float32)
    map_y = (local[..., 1] * px_per_m + margin_px - 0.5).astype(np.float32)
    behind = ~(reach > 0)
    map_x[behind], map_y[behind] = -1e4, -1e4
    image = cv2.remap(texture, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=90.0)
    return _camera_image(lens, image, noise, rng)


def render_view(lens: FisheyeLens, board: Board, pose: tuple[np.ndarray, np.ndarray], rays: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """The gray view of ``board`` at ``pose`` (``rays``: the supersampled lens's pixel directions, ``(H, W, 3)``)."""
    reach, local = _board_plane(pose, rays)
    x, y = local[..., 0] / board.square_m + 1.0, local[..., 1] / board.square_m + 1.0  # squares from the outer edge
    on_board = (reach > 0) & (x >= 0) & (x < board.cols + 1) & (y >= 0) & (y < board.rows + 1)
    dark = (np.floor(x).astype(np.int64) + np.floor(y).astype(np.int64)) % 2 == 0
    margin = (reach > 0) & (x >= -0.8) & (x < board.cols + 1.8) & (y >= -0.8) & (y < board.rows + 1.8)  # white border
    image = np.full(rays.shape[:2], 90.0)
    image[margin] = 225.0
    image[on_board & dark] = 25.0
    return _camera_image(lens, image, noise, rng)


# A ChArUco board may hang over the image's edge (at least half its corners inside), reaching further off axis.
CHARUCO_MIN_INSIDE = 0.5
CHARUCO_MAX_OFF_AXIS_DEG = 85.0


def synthetic_views(lens: FisheyeLens, board: Target, n: int, seed: int = 1, noise: float = 2.0) -> list[tuple[str, np.ndarray]]:
    """``n`` named gray views of ``board`` through ``lens`` (deterministic for a seed)."""
    rng = np.random.default_rng(seed)
    big = lens.scaled(lens.width * SUPERSAMPLE, lens.height * SUPERSAMPLE)
    ys, xs = np.mgrid[0 : big.height, 0 : big.width]
    rays = unproject(big, np.stack([xs.ravel(), ys.ravel()], axis=1)).reshape(big.height, big.width, 3)
    if isinstance(board, CharucoBoard):
        poses = board_poses(lens, board, n, rng, min_inside=CHARUCO_MIN_INSIDE, max_off_axis_deg=CHARUCO_MAX_OFF_AXIS_DEG)
        return [(f"synthetic {i}", render_charuco(lens, board, pose, rays, noise, rng)) for i, pose in enumerate(poses)]
    if not isinstance(board, Board):
        raise TypeError(f"no renderer for {type(board).__name__}")
    return [(f"synthetic {i}", render_view(lens, board, pose, rays, noise, rng)) for i, pose in enumerate(board_poses(lens, board, n, rng))]


def recovery_error(truth: FisheyeLens, fitted: FisheyeLens, max_theta_deg: float = 80.0) -> dict[str, float]:
    """How far the fitted lens is from the truth: K relative, D absolute, and the pixel distance between where
    the two put the same directions (up to ``max_theta_deg`` off axis: what the headset actually cares about)."""
    theta = np.radians(np.linspace(0.0, max_theta_deg, 81))
    phi = np.linspace(-math.pi, math.pi, 73)
    tt, pp = np.meshgrid(theta, phi)
    dirs = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], axis=-1).reshape(-1, 3)
    gap = np.linalg.norm(project(truth, dirs) - project(fitted, dirs), axis=1)
    return {
        "fx_rel": abs(fitted.fx / truth.fx - 1.0),
        "fy_rel": abs(fitted.fy / truth.fy - 1.0),
        "cx_px": abs(fitted.cx - truth.cx),
        "cy_px": abs(fitted.cy - truth.cy),
        "d_abs_max": float(np.max(np.abs(np.subtract(fitted.d, truth.d)))),
        "projection_px_max": float(gap.max()),
        "projection_px_rms": float(np.sqrt(np.mean(gap**2))),
    }
