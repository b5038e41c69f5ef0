"""Detection at a coarser scale, fingertips found again at the working resolution (feelium.touch.refine)."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.touch.config import TouchConfig
from feelium.touch.geometry import WorkingGeometry
from feelium.touch.pipeline import TouchPipeline
from feelium.touch.buffers import Scratch
from feelium.touch.refine import FineDetail, FineInputs, fine_depth, fine_window, upsample_window
from tests.touch.synth import H, ROI, W, Blob, Patch, backlight, render

CFG = TouchConfig(width=W, height=H, detect_scale=1.0)  # the full-scale path (HALF: the coarse one)
HALF = dataclasses.replace(CFG, detect_scale=0.5)
DT = 1 / 15


@settings(max_examples=40, deadline=None)
@given(
    cw=st.integers(4, 40), ch=st.integers(4, 40), factor=st.sampled_from([1.5, 2.0, 3.0]),
    x0=st.floats(0, 0.9), y0=st.floats(0, 0.9), seed=st.integers(0, 2**16),
)  # fmt: skip
def test_a_window_upsampled_is_that_window_of_the_whole_image_upsampled(cw, ch, factor, x0, y0, seed):
    coarse = np.random.default_rng(seed).random((ch, cw)).astype(np.float32)
    fw, fh = int(round(cw * factor)), int(round(ch * factor))
    whole = cv2.resize(coarse, (fw, fh), interpolation=cv2.INTER_LINEAR)
    window = (slice(int(y0 * fh), fh), slice(int(x0 * fw), fw))
    # Bilinear weights in fixed point inside OpenCV: equal to a few 1e-3 of the values' range, not bit for bit.
    np.testing.assert_allclose(upsample_window(coarse, (fw, fh), window), whole[window], atol=5e-3)


def test_the_fine_window_covers_the_boxes_and_the_margin_inside_the_image():
    coarse = WorkingGeometry.build((160, 120), (16, 12, 128, 96), (80, 60))
    fine = WorkingGeometry.build((160, 120), (16, 12, 128, 96), (160, 120))
    assert coarse.work_size == (64, 48) and fine.work_size == (128, 96)
    rows, cols = fine_window([(10, 5, 4, 3), (20, 30, 2, 2)], coarse, fine, margin=3)
    assert (cols.start, cols.stop, rows.start, rows.stop) == (17, 47, 7, 67)
    rows, cols = fine_window([(0, 0, 64, 48)], coarse, fine, margin=3)
    assert (cols.start, cols.stop, rows.start, rows.stop) == (0, 128, 0, 96)


def test_the_fine_pattern_is_learned_where_usable_and_its_first_frames_are_averaged():
    rng = np.random.default_rng(11)
    pattern = (1.0 + 0.05 * rng.standard_normal((40, 50))).astype(np.float32)
    expected = np.full((40, 50), 100.0, np.float32)
    usable = np.ones((40, 50), bool)
    usable[:, :10] = False  # always under a shadow
    detail = FineDetail(tau_s=4.0, interval_s=0.0)
    for k in range(16):
        noisy = expected * pattern * (1.0 + 0.04 * rng.standard_normal(pattern.shape)).astype(np.float32)
        detail.learn(k / 15.0, noisy, expected, usable)
    assert detail.ratio is not None
    assert np.all(detail.ratio[:, :10] == 1.0)
    error = detail.ratio[:, 10:] - pattern[:, 10:]
    # The mean of 16 lessons: the noise falls to 0.04 / 4; one frame kept for a time constant would leave ~0.03.
    assert float(np.std(error)) < 0.015


def test_due_until_a_first_lesson_then_once_per_interval():
    detail = FineDetail(tau_s=4.0, interval_s=0.25)
    assert detail.due(0.0) and detail.due(1 / 15)  # nothing learned yet
    ones = np.ones((4, 4), np.float32)
    detail.learn(1 / 15, ones, ones, ones.astype(bool))
    due = [detail.due(k / 15) for k in range(2, 8)]
    assert due == [False, False, False, True, True, True]  # 0.267 s after the lesson at 1/15 s, then until the next


def _run(config, frames):
    pipe = TouchPipeline(config, (W, H), ROI)
    return [pipe.process(k * DT, frame) for k, frame in enumerate(frames)], pipe


@pytest.fixture(scope="module")
def light():
    # A back-light with fine fixed structure, as a membrane's texture gives it: the coarse reference cannot hold it.
    rng = np.random.default_rng(2)
    grain = cv2.GaussianBlur(rng.standard_normal((H, W)).astype(np.float32), (0, 0), 1.5)
    return (backlight() * (1.0 + 0.04 * grain / grain.std())).astype(np.float32)  # 4 % rms, a few px across


def test_a_press_at_half_scale_is_found_where_and_as_sharp_as_at_full_scale(light):
    rng = np.random.default_rng(3)
    frames = [render(light, rng=rng) for _ in range(30)]
    frames += [render(light, [Patch(70.3, 52.6, 0.7, radius=5.0)], rng=rng) for _ in range(8)]
    full, _ = _run(CFG, frames)
    half, pipe = _run(HALF, frames)
    assert pipe.geometry.work_size == (64, 48) and pipe.fine is not None and pipe.fine.work_size == (128, 96)
    downs = [[e for r in rs for e in r.events if e.phase == "down"] for rs in (full, half)]
    assert len(downs[0]) == len(downs[1]) == 1
    assert abs(downs[1][0].x - downs[0][0].x) < 0.3 and abs(downs[1][0].y - downs[0][0].y) < 0.3
    assert abs(downs[1][0].x - 70.3) < 0.5 and abs(downs[1][0].y - 52.6) < 0.5
    edges = [max(r.edge for r in rs) for rs in (full, half)]
    assert edges[1] == pytest.approx(edges[0], rel=0.1)


def test_a_close_hover_fires_nothing_at_half_scale_while_a_press_does(light):
    def run(shadow):
        rng = np.random.default_rng(5)
        frames = [render(light, rng=rng) for _ in range(30)] + [render(light, [shadow], rng=rng) for _ in range(40)]
        return _run(HALF, frames)[0]

    hover = run(Blob(80, 60, 0.8, sigma=14.0))
    press = run(Patch(80, 60, 0.7, radius=6.0))
    assert [e for r in hover for e in r.events] == [] and max(r.anchor for r in hover) == 0.0
    assert [e.phase for r in press for e in r.events] == ["down"]
    assert max(r.edge for r in press) > 2 * HALF.contact_edge > 2 * max(r.edge for r in hover)


def test_without_the_fine_pattern_a_textured_flat_membrane_reads_as_depth():
    """Why the pattern is learned: the coarse reference upsampled cannot hold a membrane's texture a few pixels
    across, which the fine depth then reads as shadow; learned, the flat membrane reads as flat."""
    rng = np.random.default_rng(4)
    grain = cv2.GaussianBlur(rng.standard_normal((96, 128)).astype(np.float32), (0, 0), 1.5)
    flat = (backlight(128, 96) * (1.0 + 0.04 * grain / grain.std())).astype(np.float32)
    coarse = cv2.resize(flat, (64, 48), interpolation=cv2.INTER_AREA)  # what the coarse reference holds
    whole = (slice(0, 96), slice(0, 128))
    detail = FineDetail(tau_s=4.0, interval_s=0.0)
    for k in range(8):
        frame = flat + rng.normal(0.0, 2.0, flat.shape).astype(np.float32)
        detail.learn(k / 15.0, frame, upsample_window(coarse, (128, 96), whole), np.ones(flat.shape, bool))

    def depth_of(ratio):
        frame = flat + rng.normal(0.0, 2.0, flat.shape).astype(np.float32)
        inputs = FineInputs(frame, coarse, detail=ratio)
        return fine_depth(inputs, whole, sigma=2.0, dark_level=5.0, saturation_level=250.0, scratch=Scratch())

    without, learned = float(depth_of(None).max()), float(depth_of(detail.ratio).max())
    assert without > 0.02  # the texture alone, an eighth of the candidate threshold deep
    assert learned < 0.6 * without  # what is left is mostly the test frame's own sensor noise


def test_the_light_grids_put_one_predicted_pixel_on_each_working_pixel():
    """At 0.5 the light is predicted on a frame scaled to the detection size, over the ROI scaled: its pixel centres
    are the detection image's (to_camera); an ROI at odd pixels has no such grid, and scale 1 asks for none."""
    pipe = TouchPipeline(HALF, (W, H), ROI)
    grids = pipe.light_grids
    assert grids is not None and grids.average_of == 2
    assert grids.coarse == ((80, 60), (8, 6, 64, 48)) and grids.fine == ((W, H), ROI)
    (sw, _), (bx, by, _, _) = grids.coarse
    for wx, wy in ((0, 0), (63, 47), (10.5, 3.25)):
        # A pixel of the scaled frame maps to the camera as a working pixel does: same scale, offset by the box.
        scale = W / sw
        camera = ((bx + wx + 0.5) * scale - 0.5, (by + wy + 0.5) * scale - 0.5)
        assert pipe.geometry.to_camera(wx, wy) == pytest.approx(camera)
    assert TouchPipeline(HALF, (W, H), (17, 12, 128, 96)).light_grids is None
    assert TouchPipeline(CFG, (W, H), ROI).light_grids is None
