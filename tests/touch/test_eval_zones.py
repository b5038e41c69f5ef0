"""`eval`'s breakdown by face zone (added key ``zones``): each trial in the zone of its labelled skin point."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.events import TouchEvent
from feelium.lab.touch.evaluate import TrialData, build_report
from feelium.lab.touch.zones import face_zone
from feelium.recording import Contact, Labels
from feelium.skin.face import FaceModel

FACE = FaceModel.for_frame(1280, 960)


def _trial(label: str, u: float, v: float, *, fired_at: tuple[float, float] | None, face: FaceModel | None = FACE) -> TrialData:
    """A trial labelled at skin (u, v); a touch landing at camera ``fired_at`` (None: nothing fired)."""
    x, y = (float(c) for c in FACE.to_camera(u, v))
    contacts = (Contact(1.0, 1.3, np.array([[1.0, x, y], [1.3, x, y]])),) if label == "tap" else ()
    events = []
    if fired_at is not None:
        fx, fy = fired_at
        events = [
            TouchEvent(1, "down", None, 1.05, fx, fy, u, v, 0.6, 100, 0.5),  # type: ignore[arg-type]
            TouchEvent(1, "up", "tap", 1.3, fx, fy, u, v, 0.6, 100, 0.5),  # type: ignore[arg-type]
        ]
    target = (x, y) if label == "hover" else None
    return TrialData(f"{label}-{u}-{v}", Labels(label, False, target, contacts), events, True, 100.0, face=face)


def test_zones_split_recall_and_error_by_the_labelled_skin_point() -> None:
    cx, cy = (float(c) for c in FACE.to_camera(0.5, 0.5))
    ex, ey = (float(c) for c in FACE.to_camera(0.95, 0.5))
    trials = [
        _trial("tap", 0.5, 0.5, fired_at=(cx + 3.0, cy + 4.0)),  # centre: found, 5 px off
        _trial("tap", 0.95, 0.5, fired_at=None),  # edge: missed
        _trial("tap", 0.05, 0.5, fired_at=(float(FACE.to_camera(0.05, 0.5)[0]), ey)),  # edge: found
        _trial("hover", 0.95, 0.5, fired_at=(ex, ey)),  # edge: a hover that fired
    ]
    zones = build_report("d", trials, [], np.zeros(0), 320, 240)["zones"]
    assert zones["centre"]["recall"] == 1.0 and zones["centre"]["localisation"]["error_px"]["median"] == 5.0
    assert zones["edge"]["recall"] == 0.5 and (zones["edge"]["tp"], zones["edge"]["fn"]) == (1, 1)
    assert (zones["edge"]["fp"], zones["edge"]["tn"]) == (1, 0)
    assert zones["mid"] is None and zones["unplaced"] == 0


def test_zones_are_null_without_a_face_model() -> None:
    trials = [_trial("tap", 0.5, 0.5, fired_at=None, face=None)]
    assert build_report("d", trials, [], np.zeros(0), 320, 240)["zones"] is None


@settings(max_examples=50, deadline=None)
@given(u=st.floats(0.0, 1.0), v=st.floats(0.0, 1.0))
def test_a_skin_point_round_trips_to_its_zone(u: float, v: float) -> None:
    """The zone read back from the camera pixel of (u, v) is the zone of (u, v) (away from the cuts)."""
    rho = max(abs(u - 0.5), abs(v - 0.5)) / 0.5
    if min(abs(rho - c) for c in (1 / 3, 2 / 3, 1.0)) < 1e-3:
        return
    x, y = FACE.to_camera(u, v)
    back_u, back_v = FACE.to_uv(x, y)
    assert face_zone(float(back_u), float(back_v)) == face_zone(u, v)
    assert face_zone(u, v) == ("centre" if rho < 1 / 3 else "mid" if rho < 2 / 3 else "edge")


def test_a_landing_is_measured_against_the_contact_it_landed_on_when_two_are_pressed_at_once() -> None:
    """Two fingertips 100 px apart pressed together (multitouch two-hands-5cm): each touch overlaps both contacts
    in time, and the one that lasts longer is not the one under the finger; the error is to the one under it."""
    left = Contact(1.0, 1.6, np.array([[1.0, 270.0, 240.0], [1.6, 270.0, 240.0]]))
    right = Contact(1.05, 1.4, np.array([[1.05, 370.0, 240.0], [1.4, 370.0, 240.0]]))
    events = [
        TouchEvent(1, "down", None, 1.1, 371.0, 240.0, 0.5, 0.5, 0.6, 100, 0.5),  # type: ignore[arg-type]
        TouchEvent(1, "up", "tap", 1.4, 371.0, 240.0, 0.5, 0.5, 0.6, 100, 0.5),  # type: ignore[arg-type]
    ]
    trial = TrialData("two", Labels("tap", False, None, (left, right)), events, True, 100.0)
    report = build_report("d", [trial], [], np.zeros(0), 320, 240)
    assert report["localisation"]["error_px"]["median"] == 1.0  # not 101 px to the other hand's path
