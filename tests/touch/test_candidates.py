"""Candidates and the fingertip: sub-pixel centroid of the darkening core."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from feelium.touch.candidates import find_candidates


def blob_depth(shape, blobs):
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float32)
    depth = np.zeros(shape, np.float32)
    for x, y, d, s in blobs:
        depth = np.maximum(depth, d * np.exp(-((xs - x) ** 2 + (ys - y) ** 2) / (2 * s * s)))
    return depth


KW = dict(threshold=0.15, min_area=4, core_fraction=0.75, max_candidates=6)


@given(st.floats(10.0, 50.0), st.floats(10.0, 30.0), st.floats(0.3, 1.0), st.floats(1.5, 5.0))
def test_centroid_is_sub_pixel_exact_on_a_symmetric_blob(x, y, d, s):
    cands, seg = find_candidates(blob_depth((40, 60), [(x, y, d, s)]), **KW)
    assert len(cands) == 1
    assert abs(cands[0].x - x) < 0.25 and abs(cands[0].y - y) < 0.25
    assert seg is not None


def test_core_ignores_a_trailing_arm():
    depth = blob_depth((60, 80), [(30.0, 20.0, 0.8, 3.0)])
    depth[20:60, 28:33] = np.maximum(depth[20:60, 28:33], 0.4)  # the arm's softer shadow below the fingertip
    cands, _ = find_candidates(depth, **KW)
    assert len(cands) == 1
    assert abs(cands[0].x - 30.0) < 0.5 and abs(cands[0].y - 20.0) < 1.0


def test_two_shadows_are_two_candidates_largest_first():
    depth = blob_depth((60, 100), [(20.0, 30.0, 0.7, 3.0), (70.0, 30.0, 0.7, 6.0)])
    cands, seg = find_candidates(depth, **KW)
    assert [round(c.x) for c in cands] == [70, 20]
    mask = seg.mask_of([cands[1].label], depth.shape)
    assert mask[30, 20] and not mask[30, 70]


def test_nothing_below_threshold_gives_no_candidate():
    cands, seg = find_candidates(np.full((10, 10), 0.1, np.float32), **KW)
    assert cands == [] and seg is None


def test_flat_saturated_core_still_localises():
    depth = np.zeros((20, 20), np.float32)
    depth[5:10, 8:13] = 1.0
    cands, _ = find_candidates(depth, **KW)
    assert abs(cands[0].x - 10.0) < 1e-6 and abs(cands[0].y - 7.0) < 1e-6
