"""The tiled warp re-warps only what changed and still equals the full warp: pixel for pixel at the projector's
resolution, within a grey level on a coarse grid scaled up (the resize's fixed-point weights of a piece and of
the whole may round apart)."""

from __future__ import annotations

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.lab.projector.stream import answers_at
from feelium.projector.config import ProjectorConfig
from feelium.projector.optics import coarse_maps, fit_box
from feelium.projector.renderer import Renderer
from feelium.projector.tilewarp import TileWarp, tile_rectangles
from tests.projector.helpers import truth_calibration

BORDER = (35, 25, 20)


def small_warp(
    seed: int, canvas_size: tuple[int, int], frame_size: tuple[int, int], scale: tuple[int, int] = (1, 1)
) -> TileWarp:
    """A random smooth map (a rotation, a scale and a bulge) that also reads outside the canvas; with ``scale``
    for a coarse grid of the box (feelium.projector.optics), as the renderer builds it."""
    rng = np.random.default_rng(seed)
    cw, ch = canvas_size
    fw, fh = frame_size
    box = (int(rng.integers(0, 9)), int(rng.integers(0, 9)), fw - int(rng.integers(0, 9)), fh - int(rng.integers(0, 9)))
    ys, xs = np.mgrid[0:fh, 0:fw].astype(np.float32)
    angle, zoom = rng.uniform(-0.6, 0.6), rng.uniform(0.4, 1.6)
    u, v = (xs - fw / 2) / fw, (ys - fh / 2) / fh
    bulge = 1 + rng.uniform(-0.3, 0.3) * (u * u + v * v)
    map_x = cw / 2 + zoom * bulge * cw * (np.cos(angle) * u - np.sin(angle) * v)
    map_y = ch / 2 + zoom * bulge * ch * (np.sin(angle) * u + np.cos(angle) * v)
    if scale != (1, 1):
        box = fit_box(box, frame_size, scale[1])
        map1, map2 = coarse_maps(map_x, map_y, box, scale)
    else:
        x0, y0, x1, y1 = box
        crop = (slice(y0, y1), slice(x0, x1))
        map1, map2 = cv2.convertMaps(map_x[crop].astype(np.float32), map_y[crop].astype(np.float32), cv2.CV_16SC2)
    return TileWarp(map1, map2, box, canvas_size, (fw, fh), BORDER, scale)


rects = st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 0.6), st.floats(0, 0.6))


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    canvas_w=st.integers(20, 90),
    canvas_h=st.integers(20, 70),
    changes=st.lists(st.lists(rects, min_size=0, max_size=3), min_size=1, max_size=6),
)
def test_tiled_warp_equals_full_warp_over_random_canvases_and_changed_rects(seed, canvas_w, canvas_h, changes):
    warp = small_warp(seed, (canvas_w, canvas_h), (320, 240))
    rng = np.random.default_rng(seed)
    canvas = rng.integers(0, 256, (canvas_h, canvas_w, 3), np.uint8)
    frames = [warp.warp(canvas)]
    expected = [warp.full(canvas)]
    for rect_list in changes:
        canvas = canvas.copy()
        for fx, fy, fw, fh in rect_list:
            x0, y0 = int(fx * canvas_w), int(fy * canvas_h)
            x1, y1 = x0 + 1 + int(fw * canvas_w), y0 + 1 + int(fh * canvas_h)
            patch = canvas[y0:y1, x0:x1]
            patch[...] = rng.integers(0, 256, patch.shape, np.uint8)
        frames.append(warp.warp(canvas))
        expected.append(warp.full(canvas))
    for got, want in zip(frames, expected):
        assert np.array_equal(got, want)  # every frame handed out, too: none was written after


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    scale=st.sampled_from([(1, 2), (2, 3)]),
    changes=st.lists(st.tuples(st.lists(rects, min_size=0, max_size=3), st.booleans()), min_size=1, max_size=8),
)
def test_scaled_up_tiled_warp_stays_within_a_grey_level_of_the_full_one(seed, scale, changes):
    """Re-warped pieces scaled up with their margins, their neighbours' edges redone, held frames kept:
    every frame handed out stays within 1 of the full warp of its canvas (random canvases: the worst case)."""
    warp = small_warp(seed, (80, 60), (320, 240), scale)
    rng = np.random.default_rng(seed)
    canvas = rng.integers(0, 256, (60, 80, 3), np.uint8)
    kept = [(warp.warp(canvas), warp.full(canvas))]
    for rect_list, keep in changes:
        canvas = canvas.copy()
        for fx, fy, fw, fh in rect_list:
            x0, y0 = int(fx * 80), int(fy * 60)
            patch = canvas[y0 : y0 + 1 + int(fh * 60), x0 : x0 + 1 + int(fw * 80)]
            patch[...] = rng.integers(0, 256, patch.shape, np.uint8)
        frame = warp.warp(canvas)
        if keep:
            kept.append((frame, warp.full(canvas)))
        assert np.abs(frame.astype(int) - warp.full(canvas).astype(int)).max() <= 1
    for frame, want in kept:
        assert np.abs(frame.astype(int) - want.astype(int)).max() <= 1


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**16), pixels=st.lists(st.tuples(st.integers(0, 5), st.integers(-1, 0), st.integers(0, 4), st.integers(-1, 0)), min_size=1, max_size=8))
def test_single_pixels_on_source_tile_edges_reach_every_destination_pixel_that_reads_them(seed, pixels):
    """A change in the last or first column (row) of a source tile: bilinear taps reach across tile edges."""
    warp = small_warp(seed, (90, 70), (320, 240))
    rng = np.random.default_rng(seed)
    canvas = rng.integers(0, 256, (70, 90, 3), np.uint8)
    warp.warp(canvas)
    for tx, dx, ty, dy in pixels:
        x, y = min(89, max(0, 16 * tx + dx)), min(69, max(0, 16 * ty + dy))
        canvas[y, x] = 255 - canvas[y, x]
        assert np.array_equal(warp.warp(canvas), warp.full(canvas))


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    steps=st.lists(st.tuples(st.lists(rects, max_size=3), st.booleans(), st.integers(0, 3)), min_size=2, max_size=14),
)
def test_reused_buffers_are_brought_up_to_date_and_held_frames_are_never_written(seed, steps):
    """Consumers keep some frames and let others go: a buffer nobody holds is reused (it must first catch
    up with what changed while it was out), a held one never changes."""
    warp = small_warp(seed, (80, 60), (320, 240))
    rng = np.random.default_rng(seed)
    canvas = rng.integers(0, 256, (60, 80, 3), np.uint8)
    held: list[tuple[np.ndarray, np.ndarray]] = []
    for rect_list, keep, release in steps:
        for fx, fy, fw, fh in rect_list:
            x0, y0 = int(fx * 80), int(fy * 60)
            patch = canvas[y0 : y0 + 1 + int(fw * 80), x0 : x0 + 1 + int(fh * 60)]
            patch[...] = rng.integers(0, 256, patch.shape, np.uint8)
        frame = warp.warp(canvas)
        assert np.array_equal(frame, warp.full(canvas))
        if keep:
            held.append((frame, frame.copy()))
        del held[:release]
        del frame
    for frame, copy in held:
        assert np.array_equal(frame, copy)
    assert warp.allocated <= len(steps)


def test_a_frame_nobody_holds_is_reused_instead_of_allocating():
    warp = small_warp(5, (64, 48), (320, 240))
    canvas = np.zeros((48, 64, 3), np.uint8)
    for i in range(20):
        canvas[i % 48, (3 * i) % 64] = 200
        warp.warp(canvas)
    assert warp.allocated == 2  # the newest frame and the one being drawn


def test_a_single_changed_pixel_is_rewarped_and_nothing_else():
    warp = small_warp(3, (64, 48), (320, 240))
    canvas = np.full((48, 64, 3), 100, np.uint8)
    first = warp.warp(canvas)
    canvas[20, 30, 1] = 101
    second = warp.warp(canvas)  # the caller changed its own array in place: still seen
    assert 0 < warp.last_dirty_fraction < 0.5
    assert np.array_equal(second, warp.full(canvas)) and second is not first
    assert warp.warp(canvas) is second and warp.last_dirty_fraction == 0.0  # nothing changed: the same frame


def test_wrong_canvas_is_refused():
    warp = small_warp(1, (64, 48), (320, 240))
    try:
        warp.warp(np.zeros((48, 63, 3), np.uint8))
    except ValueError as exc:
        assert "64x48" in str(exc)
    else:
        raise AssertionError("a canvas of the wrong size was warped")


def test_renderer_frames_over_a_face_video_with_answers_equal_the_full_warp():
    renderer = Renderer(ProjectorConfig(), truth_calibration())
    rng = np.random.default_rng(7)
    faces = [renderer.fit_face(rng.integers(0, 256, (90, 120, 3), np.uint8)) for _ in range(2)]
    for i in range(24):
        now = 1.0 + i / 30
        face = faces[int(now * 12) % 2] if i < 12 else None  # a face video, then the animated avatar
        canvas = renderer.canvas(now, face, answers_at(now, seed=1))
        assert np.array_equal(renderer.warp(canvas), renderer.tiles.full(canvas)), i


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 12), st.integers(1, 40), st.floats(0.0, 1.0))
def test_tile_rectangles_cover_exactly_the_marked_tiles_without_overlap(seed, rows, cols, density):
    tiles = np.random.default_rng(seed).random((rows, cols)) < density
    covered = np.zeros((rows, cols), np.int32)
    for r0, r1, c0, c1 in tile_rectangles(tiles):
        assert 0 <= r0 < r1 <= rows and 0 <= c0 < c1 <= cols
        covered[r0:r1, c0:c1] += 1
    np.testing.assert_array_equal(covered, tiles.astype(np.int32))


def test_a_blob_of_equal_runs_is_one_rectangle():
    tiles = np.zeros((6, 10), bool)
    tiles[1:5, 2:7] = True
    assert tile_rectangles(tiles) == [(1, 5, 2, 7)]
