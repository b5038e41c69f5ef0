"""The pipeline over the whole front face: the face mask, its u, v, and the unchanged rectangle without it."""

import numpy as np
import pytest

from feelium.skin.face import FaceModel
from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline
from tests.touch.synth import H, ROI, W, Blob, Patch, backlight, render

CFG = TouchConfig(width=W, height=H, detect_scale=1.0)  # GOLDEN was pinned on the full-scale path

# Events of the paper's rectangle on the frames below, produced by the pipeline *before* the face model was
# added (commit cbcf20d): (id, phase, kind, t, x, y, u, v, depth, area). Without a face model nothing may change.
GOLDEN = [
    (1, "down", None, 0.733333, 51.9806, 40.9845, 0.285, 0.30713, 0.6085, 177),
    (1, "move", None, 0.8, 54.0011, 42.012, 0.30079, 0.31783, 0.6077, 177),
    (1, "move", None, 0.866667, 55.9884, 42.978, 0.31632, 0.3279, 0.6096, 177),
    (1, "move", None, 0.933333, 58.0171, 44.0041, 0.33216, 0.33858, 0.6028, 177),
    (1, "move", None, 1.0, 60.0021, 44.9875, 0.34767, 0.34883, 0.6058, 177),
    (1, "move", None, 1.066667, 61.9906, 46.0118, 0.36321, 0.3595, 0.6087, 177),
    (1, "move", None, 1.133333, 63.9801, 47.0158, 0.37875, 0.36996, 0.6053, 177),
    (1, "move", None, 1.2, 65.9938, 47.9878, 0.39448, 0.38008, 0.6092, 177),
    (1, "move", None, 1.266667, 67.994, 48.9883, 0.41011, 0.3905, 0.6043, 177),
    (1, "move", "hold", 1.333333, 70.0142, 49.9844, 0.42589, 0.40088, 0.6084, 177),
    (1, "move", "hold", 1.4, 71.9985, 50.9975, 0.44139, 0.41143, 0.6075, 177),
    (1, "up", "hold", 1.466667, 71.9985, 50.9975, 0.44139, 0.41143, 0.6075, 177),
    (2, "down", None, 2.066667, 110.3589, 30.5708, 0.74109, 0.19865, 0.6505, 135),
    (3, "down", None, 2.066667, 40.0145, 80.0045, 0.19152, 0.71359, 0.6, 137),
    (2, "up", "tap", 2.4, 110.3468, 30.5907, 0.74099, 0.19886, 0.6486, 138),
    (3, "up", "tap", 2.4, 39.9924, 79.9903, 0.19135, 0.71344, 0.6014, 137),
]


def golden_frames():
    rng = np.random.default_rng(17)
    light = backlight()
    frames = [render(light, rng=rng) for _ in range(10)]
    frames += [render(light, [Patch(50.0 + 2 * k, 40.0 + k, 0.7, 6.0)], rng=rng) for k in range(12)]
    frames += [render(light, [Blob(100.0, 70.0, 0.35, 8.0)], rng=rng) for _ in range(8)]
    frames += [render(light, [Patch(110.3, 30.6, 0.8, 5.0), Patch(40.0, 80.0, 0.75, 5.0)], rng=rng) for _ in range(6)]
    frames += [render(light, rng=rng) for _ in range(8)]
    return frames


def run(pipe, frames):
    events = []
    for k, frame in enumerate(frames):
        events += pipe.process(k / 15, frame).events
    return events + list(pipe.finish())


def rows(events):
    return [
        (e.id, e.phase, e.kind, round(e.t, 6), round(e.x, 4), round(e.y, 4), round(e.u, 5), round(e.v, 5),
         round(e.depth, 4), e.area)
        for e in events
    ]  # fmt: skip


def test_without_a_face_model_the_rectangle_gives_the_same_events_as_before():
    assert rows(run(TouchPipeline(CFG, (W, H), ROI), golden_frames())) == GOLDEN


@pytest.fixture(scope="module")
def small_face():
    """A face filling the middle 60 % of a fully lit frame: the lit rectangle is larger than the face."""
    return FaceModel.for_frame(W, H, fill=0.6)


def press_frames(x, y):
    rng = np.random.default_rng(5)
    light = backlight()
    frames = [render(light, rng=rng) for _ in range(10)]
    frames += [render(light, [Patch(x, y, 0.75, 5.0)], rng=rng) for _ in range(8)]
    return frames + [render(light, rng=rng) for _ in range(8)]


def test_a_press_off_the_face_is_not_a_touch_even_inside_the_roi(small_face):
    x, y = 14.0, 12.0
    assert not small_face.mask()[int(y), int(x)]
    frames = press_frames(x, y)
    assert run(TouchPipeline(CFG, (W, H), (0, 0, W, H)), frames)  # the rectangle sees it
    assert run(TouchPipeline(CFG, (W, H), (0, 0, W, H), face=small_face), frames) == []


def test_a_press_on_the_face_reports_the_face_u_v(small_face):
    x, y = 95.0, 70.0
    assert small_face.mask()[int(y), int(x)]
    events = run(TouchPipeline(CFG, (W, H), None, face=small_face), press_frames(x, y))
    assert [e.phase for e in events] == ["down", "up"]
    down = events[0]
    assert abs(down.x - x) < 0.7 and abs(down.y - y) < 0.7
    u, v = small_face.to_uv(down.x, down.y)
    assert (down.u, down.v) == pytest.approx((float(u), float(v)), abs=1e-9)
    assert down.u > 0.5 and down.v > 0.5  # right of and below the axis, as the camera sees it


def test_the_roi_defaults_to_the_face_box_and_a_model_for_another_frame_is_refused(small_face):
    assert TouchPipeline(CFG, (W, H), None, face=small_face).roi == small_face.roi()
    with pytest.raises(ValueError, match="face model"):
        TouchPipeline(CFG, (W * 2, H * 2), None, face=small_face)
