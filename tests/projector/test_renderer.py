"""Answers land at the touched spot, checked in projector pixels through the calibration."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from feelium.interactions.answers import Answer
from feelium.projector.config import ProjectorConfig
from feelium.projector.layers import DRAWERS
from feelium.projector.renderer import Renderer
from tests.interactions.touches import at_uv
from tests.projector.helpers import centroid, truth_calibration

CONFIG = ProjectorConfig()


@pytest.fixture(scope="module")
def renderer() -> Renderer:
    return Renderer(CONFIG, truth_calibration())


@pytest.mark.parametrize(
    "answer",
    [
        Answer("warm_pulse", 0.0, 0.3, 0.3, 1.6),
        Answer("heart", 0.0, 0.73, 0.58, 2.0, {"from": "partner"}),
        Answer("ripple", 0.0, 0.6, 0.7, 1.2),
        Answer("palm_glow", 0.0, 0.45, 0.75, detail={"side": "partner"}),
    ],
    ids=lambda a: a.kind,
)
def test_answer_is_drawn_where_the_touch_was_through_the_fisheye(renderer, answer):
    now = 0.6
    plain = renderer.render(now, None, [])
    with_answer = renderer.render(now, None, [answer])
    diff = np.abs(with_answer.astype(np.int16) - plain.astype(np.int16)).sum(axis=2)
    expected = renderer.calibration.to_projector(*at_uv(answer.u, answer.v))
    got = centroid(np.where(diff > 20, diff, 0))
    assert np.hypot(got[0] - expected[0], got[1] - expected[1]) < 12.0  # the spot, through the non-linear warp
    far = diff[int(expected[1]) + 200 :, :] if expected[1] < 400 else diff[: int(expected[1]) - 200, :]
    assert (far > 20).mean() < 0.002  # and nowhere else


def test_frame_is_native_resolution_and_outside_the_patch_is_dark(renderer):
    frame = renderer.render(0.0, None, [Answer("breathing", 0.0, 0.5, 0.5)])
    assert frame.shape == (720, 1280, 3) and frame.dtype == np.uint8
    assert frame[5, 5].max() < 60 and frame[360, 640].max() > 100


def test_every_answer_kind_has_a_drawer_and_draws_something():
    # Under the sensing floor alone: the fade floor lifts (and so scales) every answer with the picture, tested below.
    renderer = Renderer(replace(CONFIG, fade_floor=0.0), truth_calibration())
    kinds = ["ripple", "warm_pulse", "heart", "palm_glow", "breathing", "shimmer", "stroke", "ignite", "prompt"]
    assert sorted(DRAWERS) == sorted(kinds)
    stroke = ((0.2, 0.3), (0.4, 0.35), (0.5, 0.5))
    detail = {"stroke": {"points": stroke}, "ignite": {"strokes": (stroke,)}, "prompt": {"text": "draw: cat"}}
    base = renderer.canvas(0.5, None, [])
    for kind in kinds:
        answer = Answer(kind, 0.0, 0.5, 0.5, 3.0, detail.get(kind, {}))  # type: ignore[arg-type]
        drawn = renderer.canvas(0.5, None, [answer])
        assert (np.abs(drawn.astype(int) - base).sum(axis=2) > 30).sum() > 50, kind


def test_fading_answers_disappear_at_their_end(renderer):
    a = Answer("warm_pulse", 0.0, 0.5, 0.5, 1.0)
    assert np.array_equal(renderer.canvas(1.0, None, [a]), renderer.canvas(1.0, None, []))


def test_face_replaces_the_avatar_and_must_be_canvas_sized(renderer):
    face = np.full((100, 80, 3), (10, 200, 30), np.uint8)
    fitted = renderer.fit_face(face)
    assert fitted.shape == (384, 512, 3)
    frame = renderer.render(0.0, fitted, [])
    f = renderer.lift.floor  # this dark green face is lifted past the sensing floor by the fade floor
    assert f > renderer.config.sensing_floor
    lifted = tuple(255 * f + c * (1 - f) for c in (10, 200, 30))
    assert tuple(int(c) for c in frame[360, 640]) == pytest.approx(lifted, abs=2)
    with pytest.raises(ValueError, match="fit_face"):
        renderer.canvas(0.0, face, [])


def test_sensing_floor_keeps_the_patch_lit_and_zero_turns_it_off():
    black = np.zeros((384, 512, 3), np.uint8)
    lit = Renderer(ProjectorConfig(sensing_floor=0.45, fade_floor=0.0), truth_calibration()).render(0.0, black, [])
    off = Renderer(ProjectorConfig(sensing_floor=0.0, fade_floor=0.0), truth_calibration()).render(0.0, black, [])
    assert lit[360, 640].min() == pytest.approx(115, abs=1)  # 0.45 of full scale: the camera still sees the skin
    assert off[360, 640].max() == 0


def test_a_black_picture_is_lifted_to_the_fade_floor_and_a_bright_face_is_left_alone():
    renderer = Renderer(ProjectorConfig(sensing_floor=0.45, fade_floor=0.75), truth_calibration())
    black = np.zeros((384, 512, 3), np.uint8)
    assert renderer.render(0.0, black, [])[360, 640].min() == pytest.approx(191, abs=1)  # a fade: 0.75 grey
    face = np.full((384, 512, 3), 150, np.uint8)
    face[100:300, 150:350] = 20  # dark features; mean grey 0.57, 0.76 once the sensing floor lifts it
    face[:80] = 255
    canvas = renderer.canvas(0.0, face, [])
    assert renderer.lift.floor == pytest.approx(0.45)
    assert canvas[200, 250, 0] == pytest.approx(115 + 20 * 0.55, abs=1)
    # Half as bright (a fade half way): lifted until its mean grey is the fade floor again.
    half = renderer.canvas(0.0, face // 2, [])
    assert renderer.lift.floor > 0.45
    assert float(cv2.cvtColor(half, cv2.COLOR_BGR2GRAY).mean()) == pytest.approx(0.75 * 255, abs=1.5)


def test_a_whole_skin_answer_still_brightens_a_lifted_picture():
    renderer = Renderer(ProjectorConfig(sensing_floor=0.45, fade_floor=0.75), truth_calibration())
    black = np.zeros((384, 512, 3), np.uint8)
    base = renderer.canvas(1.0, black, []).astype(int)
    glow = renderer.canvas(1.0, black, [Answer("breathing", 0.0, 0.5, 0.5, 3.0)]).astype(int)
    assert renderer.lift.floor == pytest.approx(0.75)  # measured on the picture, not on the answer drawn over it
    assert (glow - base).sum(axis=2).min() > 20


def test_calibration_for_another_projector_is_refused():
    with pytest.raises(ValueError, match="recalibrate"):
        Renderer(ProjectorConfig(width=1920, height=1080), truth_calibration())
