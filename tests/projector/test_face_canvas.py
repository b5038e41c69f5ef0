"""With ``[touch] face_model = "sphere"`` the touch's u, v are places on the face: the projector draws there too."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

from feelium.events import TouchEvent
from feelium.interactions.answers import Answer
from feelium.projector.config import ProjectorConfig
from feelium.projector.renderer import Renderer, canvas_map
from feelium.sim.projection import FisheyeWarp
from feelium.skin.annotation import annotate
from feelium.skin.regions import Regions
from feelium.interactions.config import InteractionsConfig
from feelium.touch.config import TouchConfig
from feelium.touch.face import face_for
from feelium.touch.service import _default_pipeline
from tests.projector.helpers import CAMERA, ROI, centroid, truth_calibration

SPHERE = dataclasses.replace(TouchConfig(), face_model="sphere")


@functools.cache
def _renderer(with_face: bool) -> Renderer:
    calibration = truth_calibration()
    return Renderer(ProjectorConfig(), calibration, face_for(SPHERE, calibration.camera_size) if with_face else None)


def _answer_centre(renderer: Renderer, u: float, v: float) -> tuple[float, float]:
    answer = Answer("heart", 0.0, u, v, 2.0, {"from": "partner"})
    frame = renderer.render(1.0, None, [answer]).astype(np.int16)
    bare = renderer.render(1.0, None, []).astype(np.int16)
    diff = np.abs(frame - bare).sum(axis=2)
    diff[diff < 40] = 0
    return centroid(diff)


@pytest.mark.parametrize("where", [(320.0, 240.0), (150.0, 120.0), (500.0, 380.0), (560.0, 90.0)])
def test_an_answer_at_a_face_touch_lands_on_the_touched_spot(where):
    """Camera point -> face u, v (what the pipeline reports) -> the renderer's canvas -> projector pixel: the
    simulator's own fisheye warp (the truth) of the same camera point."""
    calibration = truth_calibration()
    face = face_for(SPHERE, calibration.camera_size)
    assert face is not None
    x, y = where
    u, v = (float(a) for a in face.to_uv(x, y))
    got = _answer_centre(_renderer(True), u, v)
    px, py = FisheyeWarp().camera_to_projector(np.array([x]), np.array([y]))
    assert np.hypot(got[0] - px[0], got[1] - py[0]) < 25.0, (got, (px[0], py[0]))
    if where != (320.0, 240.0):  # off the axis, the same u, v without the model are another spot of the skin
        plain = _answer_centre(_renderer(False), u, v)
        assert np.hypot(plain[0] - got[0], plain[1] - got[1]) > 5.0


def test_the_canvas_map_without_a_face_is_the_roi_rectangle():
    calibration = truth_calibration()
    xs, ys = np.array([ROI[0], ROI[0] + ROI[2]], np.float32), np.array([ROI[1], ROI[1] + ROI[3]], np.float32)
    mx, my = canvas_map(xs, ys, calibration, (1024, 768), None)
    assert mx.tolist() == pytest.approx([0.0, 1024.0]) and my.tolist() == pytest.approx([0.0, 768.0])


def test_face_map_scales_camera_points_of_another_frame_size():
    calibration = truth_calibration()
    big = face_for(SPHERE, (1280, 960))
    small = face_for(SPHERE, CAMERA)
    xs, ys = np.array([100.0, 320.0, 600.0], np.float32), np.array([50.0, 240.0, 400.0], np.float32)
    a = canvas_map(xs, ys, calibration, (1000, 750), small)
    b = canvas_map(xs, ys, calibration, (1000, 750), big)
    assert np.allclose(a[0], b[0], atol=0.05, equal_nan=True) and np.allclose(a[1], b[1], atol=0.05, equal_nan=True)


def test_the_daemons_pipeline_and_annotation_use_the_face_model_from_the_config():
    pipeline = _default_pipeline(SPHERE, CAMERA, ROI)
    assert pipeline.face == face_for(SPHERE, CAMERA)
    assert _default_pipeline(TouchConfig(), CAMERA, ROI).face is None
    calibration = truth_calibration()
    face = face_for(SPHERE, calibration.camera_size)
    regions = Regions.from_config(InteractionsConfig())
    x, y = (float(a) for a in face.to_camera(0.5, 0.2))  # the head region's centre, on the face
    event = TouchEvent(1, "down", None, 0.0, x, y, 0.5, 0.2, 0.6, 300, 0.7)
    assert annotate(event, calibration, regions, face).extra["region"] == "head"


def test_a_camera_inside_the_envelope_is_checked_at_load():
    with pytest.raises(ValueError, match="inside the envelope"):
        dataclasses.replace(TouchConfig(), face_camera_behind_mm=400.0)
