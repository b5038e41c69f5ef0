"""The back-light prediction against the simulator's light model, and its feed for the touch service."""

from __future__ import annotations

import dataclasses

import numpy as np

from feelium.projector.backlight import BacklightPredictor
from feelium.projector.config import ProjectorConfig
from feelium.projector.renderer import Renderer
from feelium.sim.projection import FisheyeWarp, ProjectedLight, ProjectorOptics
from tests.projector.helpers import CAMERA, ROI, truth_calibration

OPTICS = ProjectorOptics()


def _setup():
    calibration = dataclasses.replace(truth_calibration(), black_level=OPTICS.black, gamma=OPTICS.gamma)
    config = ProjectorConfig(flat_level=OPTICS.flat_level)
    return config, calibration, ProjectedLight(FisheyeWarp(), CAMERA, OPTICS)


def _patch(image: np.ndarray) -> np.ndarray:
    x, y, w, h = ROI
    return image[y : y + h, x : x + w]


def test_flat_projection_predicts_unit_gain():
    config, calibration, _ = _setup()
    flat = np.full((720, 1280, 3), round(255 * config.flat_level), np.uint8)
    gain = BacklightPredictor(config, calibration).gain(flat)
    assert np.abs(_patch(gain) - 1.0).max() < 0.01


def test_predicted_gain_matches_the_simulated_light_of_a_talking_face():
    config, calibration, light = _setup()
    predictor = BacklightPredictor(config, calibration)
    renderer = Renderer(config, calibration)
    for t in (0.0, 0.4, 1.3):
        frame = renderer.render(t, None, [], talking=True)
        ratio = _patch(light.factor(frame) / predictor.gain(frame))
        assert np.median(np.abs(ratio - 1.0)) < 0.01
        assert np.percentile(np.abs(ratio - 1.0), 99) < 0.08  # only the thin edges of eyes and mouth differ
        assert _patch(light.factor(frame)).min() < 0.6  # the face really does change the back-light
