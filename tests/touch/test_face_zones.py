"""The whole-face bench's pure parts: zones, targets drawn in them, and where a trial's hand may go."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.lab.touch import face_zones as fz
from feelium.skin.face import FaceModel

FACE = FaceModel.for_frame(640, 480)


def test_zones_by_the_largest_offset_from_the_axis():
    assert fz.zone_of(0.5, 0.5) == "centre"
    assert fz.zone_of(0.5 + 0.5 * 0.5, 0.5) == "mid"
    assert fz.zone_of(0.5, 0.5 - 0.5 * 0.8) == "edge"
    assert fz.zone_of(0.99, 0.5) is None  # beyond EDGE_MAX: not a target


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), zone=st.sampled_from(fz.ZONES))
def test_a_drawn_target_lies_in_its_zone_and_its_box_lies_on_the_face(seed, zone):
    u, v = fz.draw_target(np.random.default_rng(seed), zone)
    assert fz.zone_of(u, v) == zone
    x, y, w, h = fz.local_box(FACE, u, v)
    assert w > 30 and h > 30
    corners = np.array([[x, y], [x + w, y], [x, y + h], [x + w, y + h]], float)
    cu, cv = FACE.to_uv(corners[:, 0], corners[:, 1])
    assert np.all((cu >= 0) & (cu < 1) & (cv >= 0) & (cv < 1))
    tx, ty = (float(c) for c in FACE.to_camera(u, v))
    assert x - 1 <= tx <= x + w + 1 and y - 1 <= ty <= y + h + 1


def test_plan_has_every_zone_and_label_and_names_are_unique():
    trials = fz.plan(2)
    assert len(trials) == 2 * len(fz.ZONES) * len(fz.LABELS)
    assert len({t.name for t in trials}) == len(trials)
    assert {(t.zone, t.label) for t in trials} == {(z, label) for z in fz.ZONES for label in fz.LABELS}
