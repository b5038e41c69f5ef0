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


def _finger_on_a_lit_membrane():
    """A pad (the frustrated reflection, 0.15 deep) on the finger's room-light shadow (0.75: the room's share in a
    lit room), which runs from just in front of the pad back towards the wrist (+y), both blurred like the map."""
    import cv2

    depth = np.zeros((80, 80), np.float32)
    depth[22:80, 32:49] = 0.75  # the finger, 8 px wide either side of x = 40, from 8 px in front of the pad
    ys, xs = np.mgrid[0:80, 0:80].astype(np.float32)
    depth += 0.15 * (((xs - 40.0) / 6.0) ** 2 + ((ys - 30.0) / 5.0) ** 2 <= 1.0)
    return cv2.GaussianBlur(depth, (0, 0), 2.0)


def test_a_lit_rooms_finger_shadow_pulls_the_core_but_not_the_part_deeper_than_the_room():
    depth = _finger_on_a_lit_membrane()
    plain = find_candidates(depth, **KW)[0][0]
    lit = find_candidates(depth, **KW, room_floor=lambda x, y: 0.75 + 0.02)[0][0]
    assert plain.y - 30.0 > 5.0  # the finger joined the core: the point slid towards the wrist
    assert abs(lit.x - 40.0) < 0.25 and abs(lit.y - 30.0) < 1.0
    assert (lit.core_depth, lit.area, lit.edge) == (plain.core_depth, plain.area, plain.edge)
    assert plain.core_point is None and lit.core_point == (plain.x, plain.y)  # where the projected gate reads the share


def test_a_floor_above_the_whole_shadow_or_unknown_keeps_the_core_centroid():
    depth = _finger_on_a_lit_membrane()
    plain = find_candidates(depth, **KW)[0][0]
    for floor in (lambda x, y: 0.95, lambda x, y: None, lambda x, y: 0.1):
        other = find_candidates(depth, **KW, room_floor=floor)[0][0]
        assert (other.x, other.y) == (plain.x, plain.y)
