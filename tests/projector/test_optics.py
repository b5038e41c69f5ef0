"""Warping on the coarsest grid that keeps every canvas pixel, then scaling up: what the skin shows stays the
full warp's within the tolerance stated here (feelium.projector.optics)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.projector.config import ProjectorConfig
from feelium.projector.optics import SCALES, canvas_density, warp_scale
from feelium.projector.renderer import Renderer
from feelium.skin.projector_map import load_or_default


@given(st.floats(0.05, 1.5))
def test_the_grid_chosen_is_the_coarsest_with_a_sample_per_canvas_pixel(density):
    num, den = warp_scale(density)
    assert num / den >= density or (num, den) == (1, 1)
    coarser = [s for s in SCALES if s[0] / s[1] < num / den]
    assert all(s[0] / s[1] < density for s in coarser)


def stand_in() -> tuple[ProjectorConfig, Renderer, Renderer]:
    """The board bench's stand-in calibration (the canvas spans 806 of 1280 projector columns), warped both ways."""
    config = ProjectorConfig()
    calibration = load_or_default(Path("/nonexistent/calibration.npz"), (config.width, config.height), (64, 48, 512, 384))
    full = Renderer(dataclasses.replace(config, warp_resolution="full"), calibration)
    return config, Renderer(config, calibration), full


def smooth_canvas() -> np.ndarray:
    return cv2.GaussianBlur(np.random.default_rng(3).integers(0, 256, (384, 512, 3), np.uint8), (0, 0), 3)


def text_canvas() -> np.ndarray:
    """Anti-aliased small text at canvas resolution: the finest detail a canvas carries."""
    canvas = np.full((384, 512, 3), 200, np.uint8)
    for row in range(14):
        cv2.putText(canvas, f"Feelium skin {row} abcdefgh", (5, 25 + 26 * row), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (20, 40, 60), 1, cv2.LINE_AA)
    return canvas


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    mse = float(((a.astype(float) - b.astype(float)) ** 2)[mask].mean())
    return 10 * np.log10(255.0**2 / mse) if mse > 0 else np.inf


@pytest.mark.parametrize(("canvas", "raw_db", "skin_db"), [(smooth_canvas, 50.0, 50.0), (text_canvas, 32.0, 40.0)])
def test_coarse_warp_matches_the_full_warp_on_the_skin(canvas, raw_db, skin_db):
    """Over the skin (2 px in from its edge, where the scaled-up edge blends with the border), in PSNR: as
    projected, and as the membrane shows it (blurred by its diffusion, in projector pixels)."""
    config, coarse, full = stand_in()
    assert coarse.warp_scale == (2, 3)
    picture = canvas()
    got, want = coarse.warp(picture), full.warp(picture)
    skin = cv2.erode(full.covered.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    ix, iy = coarse.calibration.projector_to_camera()
    sigma = config.diffusion_px / canvas_density(ix, iy)  # camera px -> projector px
    blurred = [cv2.GaussianBlur(frame, (0, 0), sigma) for frame in (got, want)]
    assert psnr(got, want, skin) >= raw_db
    assert psnr(*blurred, skin) >= skin_db


def test_full_resolution_is_kept_where_the_projector_is_coarser_than_the_canvas():
    """A map denser than 2/3 of a canvas pixel per projector pixel (the test fisheye's) warps every pixel."""
    from tests.projector.helpers import truth_calibration

    assert Renderer(ProjectorConfig(), truth_calibration()).warp_scale == (1, 1)
