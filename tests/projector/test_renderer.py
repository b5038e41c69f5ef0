"""Answers land at the touched spot, checked in projector pixels through the calibration."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


def _drawn_in_full(renderer: Renderer, now: float, face, answers, talking: bool = False) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The frame as drawn from scratch: the canvas, warped whole."""
    return renderer.tiles.full(renderer.canvas(now, face, answers, talking))


@settings(max_examples=10, deadline=None)
@given(st.floats(0.0, 60.0), st.booleans(), st.lists(st.floats(0.0, 0.3), min_size=5, max_size=25))
def test_a_repeated_face_or_avatar_pose_is_the_previous_frame_and_equals_drawing_it(start, talking, steps):
    renderer, reference = Renderer(CONFIG, truth_calibration()), Renderer(CONFIG, truth_calibration())
    face = renderer.fit_face(np.random.default_rng(int(start * 1000)).integers(0, 255, (96, 128, 3), np.uint8))
    now, previous, quiet_face_before = start, None, False
    for i, step in enumerate(steps):
        now += step
        shown = face if i % 10 >= 5 else None  # runs of the avatar, then runs of one face
        answers = [Answer("ripple", now - 0.1, 0.5, 0.5, now + 1.0)] if i % 7 == 6 else []
        frame = renderer.render(now, shown, answers, talking)
        np.testing.assert_array_equal(frame, _drawn_in_full(reference, now, shown, answers, talking))
        quiet_face = shown is not None and not answers
        assert (frame is previous) == (quiet_face and quiet_face_before) or shown is None
        previous, quiet_face_before = frame, quiet_face


def test_frames_without_answers_skip_drawing_until_the_pose_or_the_face_changes():
    renderer = Renderer(CONFIG, truth_calibration())
    first = renderer.render(1.0, None, [])
    assert renderer.render(1.0 + 1e-4, None, []) is first  # the avatar has not moved a pixel
    face = renderer.fit_face(np.full((96, 128, 3), 90, np.uint8))
    with_face = renderer.render(1.0, face, [])
    assert with_face is not first and renderer.render(1.5, face, []) is with_face
    same_pixels = face.copy()  # another array (a new upload): drawn again, never assumed equal
    again = renderer.render(1.5, same_pixels, [])
    np.testing.assert_array_equal(again, with_face)
    answer = Answer("warm_pulse", 1.5, 0.5, 0.5, 3.0)
    lit = renderer.render(1.6, same_pixels, [answer])
    assert renderer.render(1.6, same_pixels, [answer]) is not None
    assert not np.array_equal(lit, again)
