"""Tracker: debouncing, tap/hold/swipe, several simultaneous contacts, ids, area."""

from dataclasses import replace

import pytest

from feelium.touch.config import TouchConfig
from feelium.touch.tracker import Observation, Tracker

CFG = TouchConfig()
DT = 1 / 15


SHARP = 0.1  # a contact edge (depth per camera px) well above the default contact_edge
BLURRED = 0.02  # a hover's soft edge


def obs(x, y, depth=0.8, area=150, edge=SHARP):
    return Observation(x, y, x / 640, y / 480, depth, area, edge)


def run(tracker, frames, t0=0.0):
    events = []
    for k, observations in enumerate(frames):
        events += tracker.step(t0 + k * DT, observations).events
    return events


def test_tap_gives_one_down_and_one_up_of_kind_tap():
    tracker = Tracker(CFG)
    events = run(tracker, [[obs(100, 100)]] * 4 + [[]] * 6)
    assert [e.phase for e in events] == ["down", "up"]
    assert events[0].kind is None and events[1].kind == "tap"
    assert events[0].id == events[1].id == 1
    assert events[0].t == DT  # confirmed on the second touching frame


def test_single_frame_flicker_is_debounced():
    tracker = Tracker(CFG)
    assert run(tracker, [[obs(100, 100)], [], [], [], []]) == []


def test_long_contact_is_a_hold_and_short_dropout_does_not_split_it():
    tracker = Tracker(CFG)
    frames = [[obs(200, 150)]] * 10 + [[]] + [[obs(200, 150)]] * 10 + [[]] * 6
    events = run(tracker, frames)
    assert [e.phase for e in events] == ["down", "up"]
    assert events[-1].kind == "hold"


def test_long_path_is_a_swipe_with_moves():
    tracker = Tracker(CFG)
    frames = [[obs(100 + 8 * k, 200)] for k in range(12)] + [[]] * 6
    events = run(tracker, frames)
    assert events[0].phase == "down" and events[-1].phase == "up"
    assert events[-1].kind == "swipe"
    assert sum(e.phase == "move" for e in events) >= 5
    assert any(e.kind == "swipe" for e in events if e.phase == "move")


def test_jitter_does_not_make_a_swipe():
    tracker = Tracker(CFG)
    frames = [[obs(300 + (1.2 if k % 2 else -1.2), 200)] for k in range(20)] + [[]] * 6
    events = run(tracker, frames)
    assert events[-1].kind == "hold"


def test_two_simultaneous_contacts_keep_their_ids():
    tracker = Tracker(CFG)
    frames = [[obs(100 + k, 100), obs(400 - k, 300, area=3000)] for k in range(10)] + [[]] * 6
    events = run(tracker, frames)
    downs = [e for e in events if e.phase == "down"]
    ups = [e for e in events if e.phase == "up"]
    assert len(downs) == 2 and len(ups) == 2
    by_id = {e.id: e for e in downs}
    assert len(by_id) == 2
    palm = [e for e in ups if e.area == 3000]
    assert palm and abs(palm[0].x - 391) < 2  # the big shadow kept its own track and area


def test_shallow_shadow_needs_the_sustained_gate():
    cfg = replace(CFG, instant_depth=0.6, anchor_threshold=0.3, anchor_min_age_s=0.5)
    tracker = Tracker(cfg)
    events = run(tracker, [[obs(100, 100, depth=0.4)]] * 12)
    assert len(events) == 1
    assert events[0].t >= 0.5 and events[0].anchor >= 0.3


def test_wobbling_shadow_is_not_anchored():
    cfg = replace(CFG, instant_depth=0.6, anchor_threshold=0.3)
    tracker = Tracker(cfg)
    frames = [[obs(100, 100, depth=0.45 if k % 5 else 0.1)] for k in range(60)]
    assert run(tracker, frames) == []


def test_finish_releases_open_contacts():
    tracker = Tracker(CFG)
    run(tracker, [[obs(100, 100)]] * 5)
    events = tracker.finish(1.0)
    assert [e.phase for e in events] == ["up"]
    assert tracker.contacts() == []


def test_a_one_frame_press_lifting_on_the_next_frame_is_still_a_tap():
    # At 15 fps the shortest taps are deep for one frame and already lifting (shallower) on the next.
    tracker = Tracker(CFG)
    events = run(tracker, [[obs(100, 100, depth=0.8)], [obs(100, 100, depth=0.35)]] + [[]] * 6)
    assert [e.phase for e in events] == ["down", "up"]
    assert events[1].kind == "tap"


def test_a_confirmed_down_lands_on_its_deepest_frame_at_the_confirming_time():
    # A tap pressed for one frame whose lifting frame (hover-like, 5 px off) confirms it: the landing point is the
    # pressed frame's, the event's time the confirmation's.
    tracker = Tracker(CFG)
    pressed, lifting = obs(100, 100, depth=0.8, area=150), obs(105, 100, depth=0.35, area=90)
    events = run(tracker, [[pressed], [lifting]] + [[]] * 6)
    assert [e.phase for e in events] == ["down", "up"]
    down = events[0]
    assert down.t == DT
    assert (down.x, down.y, down.u, down.v) == (pressed.x, pressed.y, pressed.u, pressed.v)
    assert (down.depth, down.area) == (pressed.depth, pressed.area)


def test_a_press_still_sinking_in_lands_on_the_deeper_confirming_frame():
    tracker = Tracker(CFG)
    events = run(tracker, [[obs(100, 100, depth=0.7)], [obs(103, 100, depth=0.8)]] + [[]] * 6)
    assert (events[0].phase, events[0].x, events[0].depth, events[0].t) == ("down", 103, 0.8, DT)


def test_a_contact_that_moved_while_confirming_reports_the_move_with_the_next_frame():
    tracker = Tracker(CFG)
    frames = [[obs(100, 100)], [obs(106, 100)], [obs(106, 100)]] + [[]] * 6
    events = run(tracker, frames)
    assert [(e.phase, e.x, e.t) for e in events[:2]] == [("down", 100, DT), ("move", 106, 2 * DT)]


def test_a_shallow_shadow_after_no_gate_is_not_confirmed_by_hysteresis():
    tracker = Tracker(CFG)
    assert run(tracker, [[obs(100, 100, depth=0.35)]] * 3 + [[]] * 6) == []


def test_a_deep_blurred_shadow_is_a_hover_not_a_touch():
    # A close hover darkens like a press but its shadow has no contact edge: neither gate may pass.
    tracker = Tracker(replace(CFG, instant_depth=0.55, anchor_threshold=0.3))
    assert run(tracker, [[obs(100, 100, depth=0.7, edge=BLURRED)]] * 40) == []


def test_the_anchoring_window_starts_at_landing_not_at_the_approach():
    # A shallow approach (no edge) then a steady landed press: the score is the press's depth at once,
    # not the approach's, while the gate still waits anchor_min_age_s after landing.
    cfg = replace(CFG, instant_depth=0.9, anchor_threshold=0.4, anchor_min_age_s=0.5)
    tracker = Tracker(cfg)
    approach = [[obs(100, 100, depth=0.2, edge=BLURRED)]] * 6
    press = [[obs(100, 100, depth=0.6)]] * 14
    scores = []
    events = []
    for k, frame in enumerate(approach + press):
        step = tracker.step(k / 15, frame)
        scores.append(step.anchor)
        events.extend(step.events)
    assert scores[5] == 0.0 and scores[6] == pytest.approx(0.6)
    downs = [e for e in events if e.phase == "down"]
    assert len(downs) == 1 and downs[0].t >= 6 / 15 + 0.5


def test_losing_the_edge_restarts_the_anchoring_clock():
    cfg = replace(CFG, instant_depth=0.9, anchor_threshold=0.4, anchor_min_age_s=0.5)
    tracker = Tracker(cfg)
    # Sharp for 0.4 s, one blurred frame, sharp for 0.4 s: never landed for 0.5 s at a stretch.
    frames = [[obs(100, 100, depth=0.6)]] * 6 + [[obs(100, 100, depth=0.6, edge=BLURRED)]] + [[obs(100, 100, depth=0.6)]] * 6
    assert run(tracker, frames) == []


def test_a_finger_lifted_to_hover_between_two_pats_gives_two_taps():
    # Pressed, lifted a few millimetres (still deep, but blurred: no contact edge), pressed again.
    tracker = Tracker(CFG)
    press = [[obs(100, 100, depth=0.7)]] * 3
    lifted = [[obs(100, 100, depth=0.45, edge=BLURRED)]] * 4
    events = run(tracker, press + lifted + press + lifted + [[]] * 4)
    assert [(e.phase, e.kind) for e in events if e.phase != "move"] == [("down", None), ("up", "tap")] * 2


def test_a_swipe_whose_edge_softens_a_little_stays_one_contact():
    tracker = Tracker(CFG)
    soft = 0.8 * CFG.contact_edge  # motion blur: below the landing edge, above the release hysteresis
    frames = [[obs(100 + 6 * k, 100, depth=0.6, edge=SHARP if k < 2 else soft)] for k in range(15)] + [[]] * 4
    events = run(tracker, frames)
    assert [e.phase for e in events if e.phase != "move"] == ["down", "up"]
    assert events[-1].kind == "swipe"
