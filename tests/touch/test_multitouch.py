"""Several contacts at once, and what touched: association through crossings, split shadows, finger/palm/hug."""

from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.events import ContactShape
from feelium.lab.touch import multitouch
from feelium.sim.sessions import session_presets
from feelium.touch.candidates import find_candidates
from feelium.touch.config import TouchConfig
from feelium.touch.shape import axes_from_moments, classify, contact_shape
from feelium.touch.tracker import Observation, Tracker

CFG = TouchConfig()
DT = 1 / 15
FINGER = ContactShape("finger", 150.0, 14.0, 12.0, 1.2, 0.0)
PALM = ContactShape("palm", 8000.0, 160.0, 80.0, 2.0, 90.0)


def obs(x, y, reach=12.0, shape=FINGER, depth=0.8):
    return Observation(x, y, x / 640, y / 480, depth, 150, 0.1, shape, reach)


def run(tracker, frames):
    events = []
    for k, observations in enumerate(frames):
        events += tracker.step(k * DT, observations).events
    return events


def ups(events):
    return {e.id: e for e in events if e.phase == "up"}


# -- association -------------------------------------------------------------------------------


def test_two_swipes_crossing_head_on_keep_their_ids():
    # Two fingertips on one line in opposite directions: while they overlap the camera sees one shadow in the
    # middle, after which each id must come out on its own side (nearest-centre matching has no way to know).
    frames = []
    for k in range(24):
        a, b = 100 + 12 * k, 380 - 12 * k
        frames.append([obs((a + b) / 2, 200, reach=12 + abs(a - b) / 2)] if abs(a - b) < 24 else [obs(a, 200), obs(b, 200)])
    events = run(Tracker(CFG), frames + [[]] * 6)
    downs = {e.id: e.x for e in events if e.phase == "down"}
    assert len(downs) == 2
    left_starter = min(downs, key=downs.get)
    ends = {i: e.x for i, e in ups(events).items()}
    assert set(ends) == set(downs)
    assert ends[left_starter] > 300 and min(ends.values()) < 120
    assert all(e.kind == "swipe" for e in ups(events).values())


def test_a_swipe_crossing_a_held_touch_keeps_both_ids():
    frames = []
    for k in range(30):
        s = 60 + 10 * k
        held = obs(200, 200)
        frames.append([obs((s + 200) / 2, 200, reach=12 + abs(s - 200) / 2)] if abs(s - 200) < 24 else [held, obs(s, 200)])
    events = run(Tracker(CFG), frames + [[]] * 6)
    assert sum(e.phase == "down" for e in events) == 2
    done = ups(events)
    assert len(done) == 2
    kinds = sorted((e.kind, round(e.x)) for e in done.values())
    assert kinds[0][0] == "hold" and abs(kinds[0][1] - 200) <= 2
    assert kinds[1][0] == "swipe" and kinds[1][1] > 300


def test_a_finger_lifted_next_to_a_palm_still_releases():
    # The kept-while-merged rule must not hold a lifted finger down forever beside another shadow.
    frames = [[obs(200, 200, reach=80, shape=PALM), obs(300, 200)] for _ in range(6)]
    frames += [[obs(200, 200, reach=110, shape=PALM)] for _ in range(30)]
    events = run(Tracker(CFG), frames)
    finger = [e for e in events if e.phase == "up" and e.shape is not None and e.shape.contact == "finger"]
    assert finger and finger[0].t < 6 * DT + 1.0 + CFG.release_s + 2 * DT


def test_the_largest_kind_seen_while_down_is_kept_and_up_reports_the_widest_footprint():
    frames = [[obs(200, 200)]] * 3 + [[obs(200, 200, reach=80, shape=PALM)]] * 3 + [[obs(200, 200)]] * 3 + [[]] * 6
    events = run(Tracker(CFG), frames)
    assert events[0].shape.contact == "finger"
    up = ups(events)[events[0].id]
    assert up.shape.contact == "palm" and up.shape.area_mm2 == PALM.area_mm2
    assert up.to_json()["contact"] == "palm" and up.to_json()["contact_area_mm2"] == 8000


# -- candidates -----------------------------------------------------------------------------


def _discs(shape, discs, blur=1.5):
    depth = np.zeros(shape, np.float32)
    for x, y, r, d in discs:
        cv2.circle(depth, (x, y), r, float(d), -1)
    return cv2.GaussianBlur(depth, (0, 0), blur)


KW = dict(threshold=0.15, min_area=4, core_fraction=0.75, max_candidates=6, split_fraction=0.5)


def test_two_fingertips_5cm_apart_in_one_shadow_are_two_candidates():
    # Working image at 320x240 of a 640x480 camera at 2 px/mm: 50 mm = 50 working px. The hand's shadow joins
    # the two pads at depth 0.3, below half the pads' depth.
    depth = _discs((120, 160), [(80, 60, 30, 0.3), (55, 60, 6, 0.8), (105, 60, 6, 0.8)])
    cands, _ = find_candidates(depth, **KW)
    assert len(cands) == 2
    assert sorted(round(c.x) for c in cands) == [55, 105]
    assert sum(c.area for c in cands) == np.count_nonzero(depth > 0.15)  # the shadow shared out, not counted twice


def test_a_palm_whose_pads_are_joined_by_skin_above_the_membrane_stays_one():
    depth = _discs((120, 160), [(80, 60, 30, 0.55), (55, 60, 6, 0.8), (105, 60, 6, 0.8)])
    cands, _ = find_candidates(depth, **KW)
    assert len(cands) == 1
    assert len(find_candidates(_discs((120, 160), [(80, 60, 30, 0.3), (55, 60, 6, 0.8), (105, 60, 6, 0.8)]), **(KW | {"split_fraction": 0.0}))[0]) == 1


def test_a_soft_ring_around_a_pressed_patch_is_not_a_second_contact():
    depth = _discs((200, 200), [(100, 100, 80, 0.35), (100, 100, 62, 0.0), (100, 100, 50, 0.6)])
    cands, _ = find_candidates(depth, **KW)
    assert len(cands) == 1 and cands[0].core_depth > 0.5


# -- shape ----------------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(st.floats(8.0, 60.0), st.floats(0.3, 1.0), st.floats(0.0, 179.0))
def test_axes_from_moments_measure_a_drawn_ellipse(a, ratio, angle):
    b = max(4.0, a * ratio)
    canvas = np.zeros((160, 160), np.uint8)
    cv2.ellipse(canvas, (80, 80), (int(round(a)), int(round(b))), angle, 0, 360, 1, -1)
    ys, xs = np.nonzero(canvas)
    d = np.stack([xs - xs.mean(), ys - ys.mean()])
    cov = d @ d.T / xs.size
    major, minor, orientation = axes_from_moments(cov[0, 0], cov[1, 1], cov[0, 1])
    assert major == pytest.approx(2 * round(a) + 1, rel=0.06)
    assert minor == pytest.approx(2 * round(b) + 1, rel=0.1)
    if round(a) > 1.2 * round(b):
        assert min(abs(orientation - angle), 180 - abs(orientation - angle)) < 4.0


def test_classification_follows_the_stated_physical_sizes():
    assert classify(CFG, 250.0, 20.0) == "finger"  # a fingertip pad
    assert classify(CFG, 700.0, 40.0) == "finger"  # two fingers held together
    assert classify(CFG, 8000.0, 160.0) == "palm"  # a flat hand
    assert classify(CFG, 9000.0, 300.0) == "hug"  # a forearm along the skin: longer than any hand
    assert classify(CFG, 25000.0, 200.0) == "hug"  # a chest


def test_an_unknown_scale_gives_no_millimetres_but_still_a_kind():
    cov = (100.0, 100.0, 0.0)  # a disc of 40 px diameter
    known = contact_shape(CFG, 1257.0, cov)
    assert known.area_mm2 == pytest.approx(1257.0 / 4) and known.major_mm == pytest.approx(20.0)
    unknown = contact_shape(replace(CFG, px_per_mm=0.0), 1257.0, cov)
    assert unknown.area_mm2 is None and unknown.major_mm is None and unknown.contact == known.contact == "finger"
    assert unknown.to_json()["contact_area_mm2"] is None


# -- end to end: simulator -> pipeline -------------------------------------------------------


@pytest.mark.parametrize("name, kind, count", [("two-finger-v", "finger", 2), ("palm", "palm", 1)])
def test_scene_through_the_pipeline(name, kind, count):
    session = session_presets(1)["s1"]
    rng = np.random.default_rng([1, 7])
    scene = multitouch._scene(name, rng)
    events = multitouch.run_scene(scene, session, rng, CFG)
    scored = multitouch.score(scene, events, session.shadow.px_per_mm)
    assert scored["touches"] == count and scored["missed"] == 0 and scored["swaps"] == 0 and scored["phantoms"] == 0
    assert scored["confusion"][kind][kind] == count
    assert max(scored["errors_px"]) <= (8.0 if kind == "finger" else 16.0)
