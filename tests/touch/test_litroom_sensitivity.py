"""The lab's sensitivity after a switch: a known contact read by a copy of the pipeline, against steady light."""

from __future__ import annotations

import pytest

import feelium.lab.touch.litroom as lr
from feelium.lab.sim import protocol
from feelium.sim.sessions import session_presets
from feelium.touch import pipeline as pipeline_module
from feelium.touch.config import TouchConfig
from feelium.touch.reference import AdaptiveReference

SEED, NAME = 4, "s2-empty-001"  # the dimmest session's empty trial: the old criterion read its noise for 2.16 s


def _switch_off() -> tuple[list, list, float]:
    """The trial's hand-free twin with the lamp switched off, its twin in the steady dim room, and the switch's time."""
    item = next(i for i in protocol.plan(0.05) if i.name == NAME)
    script = protocol.build_script(item, SEED)
    session = session_presets(SEED)[item.session]
    room = lr.room_for("switch-off", item, SEED, script.duration, None)
    assert room is not None
    twin = lr.render(script, session, item, SEED, room, hands=False)
    steady = lr.render(script, session, item, SEED, None, hands=False)
    return twin, steady, room.steps[0][0]


def test_the_known_contact_reads_as_in_steady_light_soon_after_the_lamp_goes_off() -> None:
    twin, steady, switch = _switch_off()
    assert lr.sensitivity_recovery(twin, steady, TouchConfig(), switch) <= 1.0


def test_a_reference_that_does_not_follow_the_switch_never_recovers(monkeypatch: pytest.MonkeyPatch) -> None:
    """The measure can fail: with no re-seed, no re-baseline and no update after the switch the reference stays the lit
    room's and the known contact reads 0.13-0.17 deeper than in steady light, to the trial's end."""
    twin, steady, switch = _switch_off()
    update = AdaptiveReference.update
    monkeypatch.setattr(pipeline_module, "illumination_change", lambda *a, **k: None)
    monkeypatch.setattr(AdaptiveReference, "observe_gain", lambda self, gain, *a, **k: setattr(self, "gain", gain) or False)
    monkeypatch.setattr(AdaptiveReference, "update", lambda self, t, *a, **k: None if t > switch else update(self, t, *a, **k))
    assert lr.sensitivity_recovery(twin, steady, TouchConfig(), switch) == float("inf")
