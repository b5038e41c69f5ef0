"""Reusing the pipeline's working buffers frame after frame changes no result, bit for bit.

The digests below are the outputs of the pipeline before its buffers were
reused (first commit 54df552; re-pinned from the tip of branch i17h, fdc84b2,
the multi-touch candidates and shapes without buffer reuse, which the merged
pipeline matched to the bit; re-pinned on branch i17r, whose lighting step re-seeds through the
illumination tile map and whose tile map is fitted as exposure plus added light: a change of the algorithm, on
the same buffers), on seeded simulator frames that exercise every path
that writes a working-size array: touches (candidates, anchored regions, the
forced update), an exposure step (the re-baseline), added room light (the
illumination re-seed), a saturated patch, and the projected-light compensation
with its spread (NaN included). A buffer that leaks between frames or between
two stages, or any reordering of the arithmetic, changes the digest.

The compensated digest was re-pinned on branch i16t (2026-11-26), deliberately: the photometric response is
solved every 0.2 s instead of every frame once its share is known (``FIT_INTERVAL_S``), and its sums decay in one
``cv2.scaleAdd`` pass (a last-bit rounding difference). Every other change of that branch (buffers, the fast
finite paths, the light predicted into recycled arrays) kept both digests; the static one did not move.

Both digests were re-pinned on branch i17room (2026-11-27), deliberately: the frame result has a new field
(``projected_depth``), and the projected frames teach the projector's share per place, so the projected-light gate
(``contact_projected_depth``) now decides which of their shadows may land. Checked before re-pinning: with the new field left
out of the digest the static one is the old pin to the bit, and so is the projected one with the gate off.

The projected digest was re-pinned on branch i17probe (2026-11-27), deliberately: the share learned from projected
frames now follows the room (a tile's reference change, and the room factor ``k`` from a short fit learned on every
frame, hands or not: :mod:`feelium.touch.roomshare`). Checked before re-pinning: with ``room_scale`` fixed at 1 and
the follow off, the projected digest is the old pin to the bit; the static one did not move.

The projected digests (scale 1.0 and 0.5) were re-pinned on branch i16share (2026-11-27, session 15), deliberately:
the share's tiles are summed over every other row of the working image (``roomshare.LEARN_ROW_STEP``, half the cost
of its passes). Checked before re-pinning: with ``LEARN_ROW_STEP = 1`` all four projected digests are the old pins to
the bit (the branch's other changes to the share, its buffers, sums and the warm-started ``k``, kept them); the static
ones did not move.

The projected digests (scale 1.0 and 0.5) were re-pinned on branch i16touch (2026-11-27, session 16), deliberately:
at the frames' 30 fps the projector's response learns from at most 15 frames a second
(``pipeline.RESPONSE_LEARN_INTERVAL_S``; the recordings accuracy is measured on are 15 fps and learn on every frame as
before). Checked before re-pinning: with ``RESPONSE_LEARN_INTERVAL_S = 0`` all four projected digests are the old pins
to the bit (the branch's other changes, the medians, the margin's dilation, the coarse pass without edges, kept
them), also after merging main at e88dd2d (whose 0.5 pin moved for the share's probe-only pooling); the static ones
did not move.

The projected digests (scale 1.0 and 0.5, and the every-frame pin) were re-pinned on branch i17room (2026-11-27, session
17), deliberately: at a re-seed or restart of the reference the share's memories keep their variance and covariance
about their own means and start new means (``ProjectorShare.rebase``: the re-seeded reference's left-over projected
pattern is a new intercept, not slope). Checked before re-pinning: with ``rebase`` a no-op all five projected digests
are the old pins to the bit (the moments now computed by ``roomshare._centred`` change no result); the static ones
did not move.

The projected digests were re-pinned on branch i17lightgate (2026-11-27, session 19), deliberately: the projected-light
gate reads a candidate's take of the projector's light against the light present at its point
(``pipeline._present_light``: over content at ``L`` of flat grey a press takes ``f * L`` of the flat skin's light).
Checked before re-pinning: with ``PRESENT_LIGHT_FLOOR = 1`` (the light present always read as 1) every digest is the
old pin to the bit; the static ones did not move.
"""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np
import pytest

from feelium.daemon.config import Config
from feelium.lab.daemon.preloaded import rear_frames
from feelium.touch.pipeline import TouchPipeline

SIZE = (160, 120)
FPS = 30.0


def _frames() -> tuple[list[np.ndarray], tuple[int, int, int, int]]:
    """3 s of the simulated rear view with two touches, then a lighting step, room light and a saturated patch."""
    config = Config()
    frames, roi = rear_frames(config.sim, SIZE, FPS, 3.0)
    out = [f.copy() for f in frames]
    for i in range(40, 55):  # exposure up by a third: a lighting step
        out[i] = np.clip(out[i].astype(np.float32) * 1.33, 0, 255).astype(np.uint8)
    for i in range(60, 75):  # a lamp: added light changes the back-light's shape (the dim corners most)
        out[i] = np.clip(out[i].astype(np.float32) + 40.0, 0, 255).astype(np.uint8)
    for i in range(80, 90):
        out[i][50:60, 60:80] = 255
    return out, roi


def _digest(
    projected: bool, cut: bool = False, patchy: bool = False, detect_scale: float = 1.0, grids: bool = False
) -> str:
    """``cut``: hand the pipeline the light and spread already cut to its ROI (as the daemon's predictor makes
    them) instead of the whole frame's; ``patchy``: spreads zero but for a patch (at the ROI's edge, inside it) or
    everywhere, as at and between a projector's scene cuts; ``grids`` (with ``detect_scale`` < 1): the light and
    spread at the detection size (the ROI's area-averaged) and the working resolution's light by windows
    (``fine_light``), as the daemon hands them over ``TouchPipeline.light_grids``."""
    config = Config()
    touch = dataclasses.replace(config.touch, width=SIZE[0], height=SIZE[1], detect_scale=detect_scale)
    frames, roi = _frames()
    pipeline = TouchPipeline(touch, SIZE, roi)
    rng = np.random.default_rng(7)
    h, w = frames[0].shape[:2]
    lights = [np.clip(1.0 + 0.3 * rng.standard_normal((h, w)), 0.0, 3.0).astype(np.float32) for _ in range(3)]
    lights[1][5:9, 5:9] = np.nan
    spreads = [np.abs(0.03 * rng.standard_normal((h, w))).astype(np.float32) for _ in range(3)]
    if patchy:
        spreads[0][:] = 0.0
        spreads[1][: h // 3, w // 2 :] = 0.0
        spreads[1][h // 2 :, :] = 0.0
        spreads[2][:, : w // 2 + 3] = 0.0
    if cut:
        x, y, rw, rh = roi
        lights = [a[y : y + rh, x : x + rw].copy() for a in lights]
        spreads = [a[y : y + rh, x : x + rw].copy() for a in spreads]
    windows: list[tuple[int, int, int]] = []
    if grids:
        x, y, rw, rh = roi
        assert pipeline.light_grids is not None and pipeline.fine is not None
        fine = [a[y : y + rh, x : x + rw] for a in lights]
        lights = [pipeline.geometry.cut_roi(a) for a in fine]
        spreads = [pipeline.geometry.cut_roi(a[y : y + rh, x : x + rw]) for a in spreads]
    sha = hashlib.sha256()
    for i, frame in enumerate(frames):
        extra = {}
        if projected:
            extra = {"projected_light": lights[(i // 7) % 3], "projected_spread": spreads[(i // 5) % 3]}
        if grids:
            whole = fine[(i // 7) % 3]

            def fine_light(rows: slice, cols: slice, whole: np.ndarray = whole) -> np.ndarray:
                windows.append((i, rows.stop - rows.start, cols.stop - cols.start))
                return whole[rows, cols].copy()

            extra["fine_light"] = fine_light
        result = pipeline.process(i / FPS, frame, **extra)
        ref = pipeline.reference
        state = (ref.gain, pipeline.noise, pipeline.masked, pipeline.settled, pipeline.light_changes)
        sha.update(repr(_rounded((dataclasses.astuple(result), state))).encode())
        arrays = (ref.image, ref.rows, pipeline._shadow, pipeline._deep, pipeline.response.slope)
        if detect_scale < 1.0:
            arrays += (pipeline.detail.ratio,)
        for array in arrays:
            sha.update(b"-" if array is None else np.ascontiguousarray(array).tobytes())
    if grids:  # the fine pass asked for windows, smaller than its whole image but for the pattern's lessons
        fw, fh = pipeline.fine.work_size
        assert any(h * w < fw * fh for _, h, w in windows) and len({i for i, _, _ in windows}) > 10
    return sha.hexdigest()


def _rounded(value: object) -> object:
    """Floats to 6 significant digits: OpenCV's SIMD and scalar paths (chosen by a patch's memory alignment) can
    differ in the last bit of a float32 result (the contact edge's Sobel magnitude does, run to run)."""
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (tuple, list)):
        return tuple(_rounded(v) for v in value)
    return value


@pytest.mark.parametrize(
    ("projected", "expected"),
    [
        (False, "f94933c4d9d82e272ecf03605844effbc7be420787d9772698e9c3840f50c75a"),
        (True, "e35d05e9314e47354ab4c44153acae7e1f2a0b8c38799598e9b6e45f8a994d1a"),
    ],
)
def test_results_match_the_pipeline_before_buffer_reuse(projected: bool, expected: str) -> None:
    """The static digest re-pinned in session 15 (merge of i17lit) for the down landing on its deepest frame since the
    gates passed: with the tracker before it, the previous pin to the bit (as is the half-scale static one's). The
    projected digests (here and below) re-pinned in session 18 (branch i17share) for the reference that moves with
    each solve of the projector's response (``AdaptiveReference.carry``): with it a no-op, every previous pin to the
    bit."""
    assert _digest(projected) == expected


def test_light_cut_to_the_roi_gives_the_whole_frames_results() -> None:
    """The daemon predicts the projected light only over the ROI (it is all the pipeline reads): same digest."""
    assert _digest(True, cut=True) == "e35d05e9314e47354ab4c44153acae7e1f2a0b8c38799598e9b6e45f8a994d1a"


def test_the_bound_only_around_a_nonzero_spread_gives_the_whole_frames_results(monkeypatch) -> None:
    """The uncertainty bound computed only in the window around the nonzero spread (none when it is all zero)
    changes nothing against computing it over the whole working image, whatever lies where."""
    import feelium.touch.pipeline as pipeline_module

    windowed = _digest(True, patchy=True)
    monkeypatch.setattr(pipeline_module, "spread_window", lambda spread, sigma, scratch=None: (slice(None), slice(None)))
    assert windowed == _digest(True, patchy=True)


@pytest.mark.parametrize(
    ("projected", "expected"),
    [
        (False, "3e0a8316300532c3e8f88600e21f0877c90a4a97c268c5ed60660a858c19594b"),
        (True, "99b4a54e95c8d415928eead39c9eb6513116b41fe31843fbd95d006c77124274"),
    ],
)
def test_half_scale_detection_is_pinned_on_its_own(projected: bool, expected: str) -> None:
    """``[touch] detect_scale = 0.5`` (feelium.touch.refine) is its own algorithm: pinned apart from the full-scale
    digests above, which it must never move (pinned on branch i16half, 2026-11-27; re-pinned at the merge with
    i17room the same day for the new ``projected_depth`` field and the projected-light gate: with the field left
    out of the digest and the gate off, both are i16half's pins to the bit; the projected one re-pinned on branch
    i17probe for the share that follows the room: with ``room_scale`` fixed at 1 and the follow off, it is the
    previous pin to the bit; re-pinned on branch i16share for the share's tiles summed over every other row (with
    ``LEARN_ROW_STEP = 1`` the previous pin to the bit), and in session 15 for the room-light and share tiles kept
    the same part of the membrane at 0.5, ``tile_px_for`` (with it returning 16, i16share's pins to the bit); the
    projected one re-pinned in session 16 for the projector's share pooled from pixels that saw only a probe's
    variance of light when none saw the prior's (``photometric.MIN_LIGHT_VAR``: the area-averaged light at 0.5 has
    a quarter of the variance, so its first frames now give a share; with that fallback off, the previous pin to the
    bit; the full-scale digests do not move)."""
    assert _digest(projected, detect_scale=0.5) == expected


def test_half_scale_light_on_the_detection_grid_with_fine_windows_gives_the_same_results() -> None:
    """The daemon's way at ``detect_scale = 0.5``: light and spread at the detection size, the working resolution's
    light only in the fine pass's windows (``fine_light``). Handed the same values (the working light area-averaged,
    and its windows), the pipeline computes what it computes from the whole frame's light: the pinned digest (the
    projected one of the test above, re-pinned there at the merge of i16coarse with i17probe's share)."""
    expected = "99b4a54e95c8d415928eead39c9eb6513116b41fe31843fbd95d006c77124274"
    assert _digest(True, detect_scale=0.5, grids=True) == expected


def test_learning_on_every_frame_gives_the_previous_pin(monkeypatch) -> None:
    """With the response learning on every frame again (``RESPONSE_LEARN_INTERVAL_S = 0``), the daemon's way at 0.5
    is main's pin to the bit (e88dd2d's, re-pinned there in session 16 for the share's probe-only pooling): the
    response's learning rate is the only change of results on branch i16touch."""
    import feelium.touch.pipeline as pipeline_module

    monkeypatch.setattr(pipeline_module, "RESPONSE_LEARN_INTERVAL_S", 0.0)
    expected = "406e4f5892091dfbb6cae3700c249277068bf5170ad2357eea5941ae6a248041"
    assert _digest(True, detect_scale=0.5, grids=True) == expected
