"""A synthetic fisheye view of a room, so the headset sees a live, moving picture without hardware.

The room is an equirectangular panorama drawn once (walls, windows, a door,
furniture, a floor grid); each frame is that panorama seen through an
equidistant fisheye lens while the blimp slowly yaws and bobs, with a person
walking around it. Pure: the frame is a function of ``t``.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from feelium.cameras.lens import FisheyeLens

PANORAMA_WIDTH = 1024
PANORAMA_HEIGHT = 512


def _room_panorama(rng: np.random.Generator) -> np.ndarray:
    """Walls above the horizon, floor below, and some furniture to give the eye parallax-free landmarks."""
    w, h = PANORAMA_WIDTH, PANORAMA_HEIGHT
    pano = np.zeros((h, w, 3), np.uint8)
    horizon = h // 2
    wall = np.linspace(150, 200, horizon, dtype=np.float32)[:, None]
    pano[:horizon] = np.stack([wall * 0.85, wall * 0.9, wall], axis=-1).astype(np.uint8)
    floor = np.linspace(120, 60, h - horizon, dtype=np.float32)[:, None]
    pano[horizon:] = np.stack([floor * 0.55, floor * 0.7, floor * 0.9], axis=-1).astype(np.uint8)
    for x in range(0, w, w // 16):  # floor boards converge nowhere on a panorama: vertical lines suffice
        cv2.line(pano, (x, horizon), (x, h - 1), (40, 55, 75), 1)
    for y in (horizon + 30, horizon + 80, horizon + 160):
        cv2.line(pano, (0, y), (w - 1, y), (40, 55, 75), 1)
    corners = [int(w * k / 4) for k in range(4)]
    for x in corners:  # room corners
        cv2.line(pano, (x, 0), (x, horizon), (110, 115, 125), 2)
    for i, x in enumerate(corners):
        wx = x + w // 16
        if i % 2 == 0:  # a window with a bright sky
            cv2.rectangle(pano, (wx, horizon - 170), (wx + 120, horizon - 60), (235, 215, 170), -1)
            cv2.rectangle(pano, (wx, horizon - 170), (wx + 120, horizon - 60), (90, 90, 90), 3)
            cv2.line(pano, (wx + 60, horizon - 170), (wx + 60, horizon - 60), (90, 90, 90), 2)
        else:  # a door and a poster
            cv2.rectangle(pano, (wx, horizon - 150), (wx + 60, horizon), (60, 90, 140), -1)
            color = tuple(int(c) for c in rng.integers(40, 230, 3))
            cv2.rectangle(pano, (wx + 110, horizon - 140), (wx + 170, horizon - 60), color, -1)
        cv2.rectangle(pano, (wx + 20, horizon - 10), (wx + 200, horizon + 40), (50, 50, 70), -1)  # a table
    return pano


def sim_lens(width: int, height: int, fov_deg: float = 180.0) -> FisheyeLens:
    """The lens :class:`SimFisheyeRoom` renders through, in OpenCV's fisheye model (what ``GET /lens`` serves in sim).

    The sim is equidistant (radius proportional to the angle off axis), which is OpenCV's model with
    ``D = 0`` and ``f = radius / half field``, the image circle touching the frame's shorter sides.
    """
    radius = min(width, height) / 2.0
    f = radius / math.radians(fov_deg / 2.0)
    return FisheyeLens(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0, source="sim")


def _fisheye_rays(width: int, height: int, fov_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth and elevation (radians) of every output pixel of an equidistant fisheye; NaN outside its circle."""
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0  # sim_lens states the same model: keep the two together
    radius = min(width, height) / 2.0
    r = np.hypot(xs - cx, ys - cy) / radius
    theta = r * math.radians(fov_deg) / 2.0  # angle off the optical axis
    phi = np.arctan2(ys - cy, xs - cx)
    dx = np.sin(theta) * np.cos(phi)
    dy = np.sin(theta) * np.sin(phi)
    dz = np.cos(theta)
    azimuth = np.arctan2(dx, dz)
    elevation = np.arcsin(np.clip(-dy, -1.0, 1.0))
    outside = r > 1.0
    azimuth[outside] = np.nan
    elevation[outside] = np.nan
    return azimuth, elevation


class SimFisheyeRoom:
    """Renders the moving fisheye room view; deterministic for a seed.

    The lens mapping is fixed (16-bit fixed-point maps: small and fast on a
    Pi); the blimp's yaw turns the panorama under it instead. A 180 degree
    lens never looks behind, so the panorama's seam is never sampled.
    """

    def __init__(self, width: int, height: int, *, seed: int = 1, fov_deg: float = 180.0) -> None:
        self.width, self.height = width, height
        self._panorama = _room_panorama(np.random.default_rng(seed))
        azimuth, elevation = _fisheye_rays(width, height, fov_deg)
        outside = np.isnan(azimuth)
        map_x = ((np.nan_to_num(azimuth) + math.pi) / (2 * math.pi) * PANORAMA_WIDTH).astype(np.float32)
        map_y = ((math.pi / 2 - np.nan_to_num(elevation)) / math.pi * PANORAMA_HEIGHT).astype(np.float32)
        map_x[outside] = -16.0  # off the panorama: remap's constant border paints the lens's black surround
        self._map1, self._map2 = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)

    def render(self, panorama: np.ndarray) -> np.ndarray:
        """A ``PANORAMA_WIDTH x PANORAMA_HEIGHT`` equirectangular image seen through the lens.

        Panorama column ``i`` is azimuth ``2 pi i / PANORAMA_WIDTH - pi`` (positive right), row ``j``
        elevation ``pi / 2 - pi j / PANORAMA_HEIGHT`` (positive up); azimuth 0, elevation 0 is the optical axis.
        """
        return cv2.remap(
            panorama, self._map1, self._map2, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0
        )

    def frame(self, t: float) -> np.ndarray:
        """The BGR view at time ``t``: a slow yaw sweep and a person walking around."""
        yaw_px = int(round(math.sin(t * 0.1) * 0.35 * PANORAMA_WIDTH))
        pano = np.roll(self._panorama, -yaw_px, axis=1)
        walk = (0.5 + 0.5 * math.sin(t * 0.21)) * PANORAMA_WIDTH
        px, top = (int(walk) - yaw_px) % PANORAMA_WIDTH, PANORAMA_HEIGHT // 2 - 120
        cv2.ellipse(pano, (px, top + 70), (22, 70), 0, 0, 360, (70, 60, 160), -1)  # body
        cv2.circle(pano, (px, top - 10), 18, (120, 150, 200), -1)  # head
        view = self.render(pano)
        cv2.putText(view, f"SIM {t:7.2f}s", (8, self.height - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1)
        return view
