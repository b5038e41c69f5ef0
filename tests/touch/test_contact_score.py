"""Several contacts per trial scored contact by contact: ids kept, split, swapped or phantom, and what touched."""

from __future__ import annotations

import numpy as np

from feelium.events import ContactShape, TouchEvent
from feelium.lab.touch.contact_score import gesture_of, score_contacts
from feelium.lab.touch.evaluate import TrialData, score_trials
from feelium.recording import Contact, Labels


def _contact(x: float, kind: str | None = "finger", on: float = 1.0, off: float = 2.0) -> Contact:
    return Contact(on, off, np.array([[on, x, 100.0], [off, x, 100.0]]), kind)


def _event(eid: int, phase: str, t: float, x: float, kind: str = "finger") -> TouchEvent:
    shape = ContactShape(kind, 200.0, 16.0, 16.0, 1.0, 0.0) if phase == "up" else None  # type: ignore[arg-type]
    return TouchEvent(eid, phase, None, t, x, 100.0, 0.5, 0.5, 0.6, 100, 0.5, shape)  # type: ignore[arg-type]


def _touch(eid: int, x: float, kind: str = "finger", x_late: float | None = None) -> list[TouchEvent]:
    late = x if x_late is None else x_late
    return [_event(eid, "down", 1.05, x), _event(eid, "move", 1.5, late), _event(eid, "up", 2.0, late, kind)]


def _trial(contacts: tuple[Contact, ...], events: list[TouchEvent]) -> TrialData:
    return TrialData("t", Labels("hold", False, None, contacts), events, True, 100.0)


def test_two_contacts_with_their_own_ids_and_kinds_are_clean():
    got = score_contacts([_trial((_contact(100), _contact(200, "palm")), _touch(1, 102) + _touch(2, 190, "palm"))])
    assert got is not None
    assert (got["contacts"], got["touches"], got["missed"], got["split"], got["swaps"], got["phantoms"]) == (2, 2, 0, 0, 0, 0)
    assert (got["kind_right"], got["kind_scored"]) == (2, 2)
    assert got["error_px"] == {"median": 6.0, "max": 10.0}


def test_a_swap_a_split_a_phantom_a_miss_and_a_wrong_kind_are_each_counted():
    contacts = (_contact(100), _contact(200), _contact(400))
    events = _touch(1, 100, x_late=200) + _touch(2, 200) + _touch(3, 200, "palm") + _touch(4, 700)
    got = score_contacts([_trial(contacts, events)])
    assert got is not None
    assert (got["touches"], got["missed"], got["split"], got["swaps"], got["phantoms"]) == (4, 1, 2, 1, 1)
    assert got["kinds"]["finger"]["palm"] == 1 and got["kind_right"] == 2


def test_trials_without_the_contact_key_are_the_specs_alone():
    assert score_contacts([_trial((_contact(100, None),), _touch(1, 100))]) is None


def test_the_footprints_reported_on_up_are_summarised_per_true_kind():
    """Issue 17 asks for a palm and a hug "with area and shape": the report gives each true kind's median
    footprint from the `up` events of the ids on its contacts (a phantom's footprint belongs to no kind)."""
    palm_up = TouchEvent(2, "up", None, 2.0, 300.0, 100.0, 0.5, 0.5, 0.6, 100, 0.5,  # type: ignore[arg-type]
                         ContactShape("palm", 9500.0, 130.0, 90.0, 1.44, 10.0))  # type: ignore[arg-type]  # fmt: skip
    events = _touch(1, 100) + [_event(2, "down", 1.05, 300.0), palm_up] + _touch(3, 900)
    got = score_contacts([_trial((_contact(100), _contact(300, "palm")), events)])
    assert got is not None
    assert got["footprint"]["palm"] == {"n": 1, "area_mm2": 9500.0, "major_mm": 130.0, "minor_mm": 90.0, "elongation": 1.4}
    assert got["footprint"]["finger"] == {"n": 1, "area_mm2": 200.0, "major_mm": 16.0, "minor_mm": 16.0, "elongation": 1.0}
    assert "hug" not in got["footprint"]


def _moving(x0: float, x1: float, on: float, off: float, jitter: float = 0.0) -> Contact:
    """A fingertip from ``x0`` to ``x1`` over [on, off), sampled at 15 fps, ``jitter`` px of alternating tremor."""
    ts = np.arange(on, off, 1.0 / 15.0)
    xs = np.linspace(x0, x1, ts.size) + jitter * (-1.0) ** np.arange(ts.size)
    return Contact(on, off, np.column_stack([ts, xs, np.full(ts.size, 100.0)]), "finger")


def test_the_gesture_of_a_labelled_contact_is_the_trackers_rule_on_the_truth():
    """Held still 0.6 s (the tracker's hold_min_s) is a hold, to the millisecond; shorter a tap; a path of 40 px a
    swipe; a tremor under the tracker's 3 px deadband adds no path, however long."""
    assert gesture_of(_moving(100, 100, 1.0, 1.6)) == "hold"  # 1.6 - 1.0 is 0.6000000000000001, and 0.6 either way
    assert gesture_of(_moving(100, 100, 1.0, 1.0 + 0.599)) == "tap"
    assert gesture_of(_moving(100, 160, 1.0, 1.3)) == "swipe"
    assert gesture_of(_moving(100, 100, 1.0, 3.0, jitter=1.0)) == "hold"
    assert gesture_of(Contact(1.0, 1.2, None)) == "tap"  # no path: only its duration can say


def test_each_contacts_gesture_is_scored_against_its_own_id():
    """Two contacts with one trial label: a held fingertip and a swipe past it. Each id's ``up`` kind is scored
    against the gesture its own contact performed (the spec's one label per trial cannot)."""
    held, swipe = _moving(100, 100, 0.8, 3.4), _moving(40, 360, 1.3, 2.7)

    def up(eid: int, x: float, kind: str) -> TouchEvent:
        return TouchEvent(eid, "up", kind, 2.7, x, 100.0, 0.5, 0.5, 0.6, 100, 0.5, None)  # type: ignore[arg-type]

    events = [_event(1, "down", 0.9, 100.0), up(1, 100.0, "hold"), _event(2, "down", 1.4, 50.0), up(2, 360.0, "tap")]
    got = score_contacts([_trial((held, swipe), events)])
    assert got is not None
    assert got["gestures"] == {"hold": {"tap": 0, "hold": 1, "swipe": 0, "none": 0}, "swipe": {"tap": 1, "hold": 0, "swipe": 0, "none": 0}}
    assert (got["gesture_right"], got["gesture_scored"]) == (1, 2)


def test_the_single_event_rate_is_also_given_over_the_trials_with_one_contact():
    """Two hands are two events, which the spec's single-event rate counts against them; the added rate over the
    trials with one labelled contact keeps the spec's meaning, and the multi-contact trials are counted apart."""
    two = _trial((_contact(100), _contact(200)), _touch(1, 100) + _touch(2, 200))
    one = _trial((_contact(100),), _touch(1, 100))
    trials = score_trials([two, one])["trials"]
    assert trials["single_event_rate"] == 0.5
    assert trials["single_event_rate_one_contact"] == 1.0 and trials["multi_contact_detected"] == 1
