"""A drawing round's strokes are drawn once into a layer: the picture is the full redraw's, the work is the new points'."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import feelium.projector.strokes as strokes_module
from feelium.interactions.answers import Answer
from feelium.interactions.engine import MAX_STROKE_POINTS, MAX_STROKES
from feelium.projector.config import ProjectorConfig
from feelium.projector.layers import draw_stroke
from feelium.projector.renderer import Renderer
from feelium.projector.strokes import StrokeLayer, draw_segments
from tests.projector.helpers import truth_calibration

W, H = 512, 384  # the daemon's canvas: halo 7 px, core 2 px
# The layer's 8-bit premultiplied steps round apart from the canvas's own, on anti-aliased rims only: measured on
# 64 overlapping full strokes, ~4 % of the drawn pixels differ, by 1-3 grey levels; < 0.05 % by more, at most 9.
COMPOSE_TOLERANCE = 10
ROUNDED_APART = 3


def _walk(rng: np.random.Generator, n: int) -> list[tuple[float, float]]:
    p = rng.uniform(0.1, 0.9, 2)
    out = []
    for _ in range(n):
        p = np.clip(p + rng.normal(0.0, 0.012, 2), 0.02, 0.98)
        out.append((round(float(p[0]), 4), round(float(p[1]), 4)))  # as the engine rounds them
    return out


def _stroke(number: int, points, round_number: int = 1) -> Answer:
    return Answer("stroke", float(number), 0.5, 0.5, detail={"points": tuple(points), "stroke": number, "round": round_number})


def _redrawn(background: np.ndarray, answers) -> np.ndarray:
    img = background.copy()
    for answer in answers:
        draw_stroke(img, answer, 0.0)
    return img


def _background(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.integers(0, 256, (H, W, 3), np.uint8), (0, 0), 2)


def _assert_same_picture(layer: StrokeLayer, background: np.ndarray, answers) -> None:
    got = background.copy()
    layer.compose(got)
    want = _redrawn(background, answers)
    diff = np.abs(got.astype(np.int16) - want).max(axis=2)
    drawn = (want != background).any(axis=2)
    assert diff[~drawn].max(initial=0) <= 2  # off the strokes: the canvas, but where a faint rim rounds apart
    assert diff.max() <= COMPOSE_TOLERANCE, diff.max()
    assert (diff > ROUNDED_APART).sum() <= max(2, 0.001 * drawn.sum()), (diff > ROUNDED_APART).sum()


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 4), st.booleans())
def test_polyline_drawn_in_pieces_is_the_polyline(seed, step, thick):
    """draw_segments reproduces OpenCV's own per-segment drawing: pieces give the whole, pixel for pixel."""
    rng = np.random.default_rng(seed)
    thickness = int(rng.integers(3, 9)) if thick else int(rng.integers(1, 3))
    n = int(rng.integers(2, 50))
    px = [tuple(int(v) for v in p) for p in np.cumsum(rng.integers(-8, 9, (n, 2)), axis=0) + (W // 2, H // 2)]
    whole = np.zeros((H, W), np.uint8)
    cv2.polylines(whole, [np.array(px, np.int32).reshape(-1, 1, 2)], False, 255, thickness, cv2.LINE_AA)
    pieces = np.zeros((H, W), np.uint8)
    done = 1
    while done < n:
        upto = min(n, done + step)
        draw_segments(pieces, px[done - 1 : upto], done == 1, 255, thickness)
        done = upto
    assert np.array_equal(whole, pieces)


@settings(max_examples=3, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 5))
def test_a_drawing_grown_frame_by_frame_looks_as_if_redrawn_every_frame(seed, step):
    """Strokes growing a few points a frame, a dot turning into a line, two fingers at once, a new round."""
    rng = np.random.default_rng(seed)
    background = _background(seed)
    layer = StrokeLayer(W, H)
    walks = [_walk(rng, int(rng.integers(1, 60))) for _ in range(6)]
    shown = {k: 1 for k in range(len(walks))}
    for frame in range(30):
        started = min(len(walks), 1 + frame // 5)
        for k in range(started):
            if k >= started - 2:  # the newest two grow: sometimes an older stroke grows after a newer began
                shown[k] = min(len(walks[k]), shown[k] + int(rng.integers(0, step + 1)))
        answers = [_stroke(k + 1, walks[k][: shown[k]]) for k in range(started)]
        layer.update(answers)
        if frame % 3 == 2:  # every frame is drawn into the layer; every third is compared (the redraw is slow)
            _assert_same_picture(layer, background, answers)
    fresh = [_stroke(100, walks[0][:5], round_number=2)]  # the next round: the old strokes leave
    layer.update(fresh)
    _assert_same_picture(layer, background, fresh)


class _DrawCalls:
    """Counts OpenCV drawing calls and the vertices they were given."""

    NAMES = ("polylines", "fillConvexPoly", "ellipse", "circle", "line")

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.calls = {name: 0 for name in self.NAMES}
        self.vertices = 0
        for name in self.NAMES:
            monkeypatch.setattr(strokes_module.cv2, name, self._counting(name, getattr(cv2, name)))

    def _counting(self, name, function):
        def counted(img, *args, **kwargs):
            self.calls[name] += 1
            if name == "polylines":
                self.vertices += sum(len(p) for p in args[0])
            return function(img, *args, **kwargs)

        return counted

    def reset(self) -> None:
        self.calls = dict.fromkeys(self.calls, 0)
        self.vertices = 0


def test_with_64_full_strokes_a_frame_draws_only_its_new_segment(monkeypatch):
    rng = np.random.default_rng(7)
    walks = [_walk(rng, MAX_STROKE_POINTS) for _ in range(MAX_STROKES)]
    layer = StrokeLayer(W, H)
    layer.update([_stroke(k + 1, w) for k, w in enumerate(walks[:-1])] + [_stroke(MAX_STROKES, walks[-1][:-1])])
    calls = _DrawCalls(monkeypatch)
    full = [_stroke(k + 1, w) for k, w in enumerate(walks)]
    version = layer.update(full)  # the live stroke's 256th point
    assert calls.calls["polylines"] == 0 and calls.vertices == 0  # nothing old drawn again
    assert calls.calls["fillConvexPoly"] == 2 and calls.calls["ellipse"] == 2  # one segment, halo and core
    calls.reset()
    assert layer.update(full) == version  # nothing new: no drawing, same version
    assert sum(calls.calls.values()) == 0
    background = _background(3)
    _assert_same_picture(layer, background, full)


def test_a_stroke_leaving_the_skin_redraws_the_rest_once_and_the_round_end_drops_the_layer():
    rng = np.random.default_rng(11)
    walks = [_walk(rng, 30) for _ in range(5)]
    layer = StrokeLayer(W, H)
    layer.update([_stroke(k + 1, w) for k, w in enumerate(walks[:4])])
    remaining = [_stroke(k + 1, w) for k, w in enumerate(walks) if k > 0]  # stroke 1 left as stroke 5 began
    layer.update(remaining)
    _assert_same_picture(layer, _background(5), remaining)
    layer.update([])
    assert layer._arrays is None  # the 2.4 MB go with the round
    img = _background(5)
    layer.compose(img)
    assert np.array_equal(img, _background(5))


def test_renderer_shows_a_still_drawing_without_drawing_it_again():
    renderer = Renderer(replace(ProjectorConfig(), fade_floor=0.0), truth_calibration())
    rng = np.random.default_rng(2)
    answers = [_stroke(k + 1, _walk(rng, 40)) for k in range(8)]
    face = renderer.fit_face(_background(9))
    first = renderer.render(0.0, face, answers)
    assert renderer.render(1 / 30, face, answers) is first  # same face, strokes unchanged: the same frame
    grown = answers[:-1] + [_stroke(8, answers[-1].detail["points"] + ((0.5, 0.5),))]
    assert renderer.render(2 / 30, face, grown) is not first



def test_answers_move_on_at_answer_fps_and_at_once_with_a_new_face_or_answer():
    renderer = Renderer(replace(ProjectorConfig(), answer_fps=15.0), truth_calibration())
    face, other_face = renderer.fit_face(_background(9)), renderer.fit_face(_background(10))
    ripple = Answer("ripple", 0.0, 0.4, 0.4, 1.2)
    first = renderer.render(0.5, face, [ripple])
    assert renderer.render(0.5 + 1 / 30, face, [ripple]) is first  # drawn 33 ms ago: shown again
    assert renderer.render(0.57, face, [ripple]) is not first  # over 1 / answer_fps old: moves on
    moved = renderer.render(0.57, face, [ripple])
    assert renderer.render(0.58 + 0.01, other_face, [ripple]) is not moved  # a new face frame: at once
    again = renderer.render(0.58 + 0.02, other_face, [ripple])
    assert renderer.render(0.58 + 0.03, other_face, [ripple, Answer("heart", 0.6, 0.3, 0.6, 2.6)]) is not again
    reference = Renderer(replace(ProjectorConfig(), answer_fps=15.0), truth_calibration())
    assert np.array_equal(again, reference.render(0.58 + 0.01, other_face, [ripple]))  # drawn at its time
