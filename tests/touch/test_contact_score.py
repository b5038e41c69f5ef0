"""Several contacts per trial scored contact by contact: ids kept, split, swapped or phantom, and what touched."""

from __future__ import annotations

import numpy as np

from feelium.events import ContactShape, TouchEvent
from feelium.lab.touch.contact_score import score_contacts
from feelium.lab.touch.evaluate import TrialData
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
