"""Soften on firm touches and hugs, with a grace period; light taps do not soften."""

from __future__ import annotations

from feelium.events import InteractionEvent, TouchEvent
from feelium.flight.soften import SoftenTracker


def touch(id_: int, phase: str, depth: float, kind: str | None = None, t: float = 0.0) -> TouchEvent:
    return TouchEvent(id_, phase, kind, t, 100.0, 100.0, 0.5, 0.5, depth, 50, 0.5)  # type: ignore[arg-type]


def test_light_tap_does_not_soften() -> None:
    tracker = SoftenTracker(firm_depth=0.5, hold_s=0.8)
    tracker.observe(touch(1, "down", 0.2), 0.0)
    assert not tracker.active(0.1)


def test_firm_press_softens_until_release_plus_grace() -> None:
    tracker = SoftenTracker(firm_depth=0.5, hold_s=0.8)
    tracker.observe(touch(1, "down", 0.7), 0.0)
    assert tracker.active(5.0)
    tracker.observe(touch(1, "up", 0.0), 5.0)
    assert tracker.active(5.5) and not tracker.active(5.9)


def test_hug_softens_until_it_ends() -> None:
    tracker = SoftenTracker(firm_depth=0.5, hold_s=0.5)
    tracker.observe(InteractionEvent("hug", "start", 1.0), 1.0)
    assert tracker.active(3.0)
    tracker.observe(InteractionEvent("hug", "end", 4.0), 4.0)
    assert not tracker.active(4.6)


def test_a_lost_release_does_not_soften_forever() -> None:
    tracker = SoftenTracker(firm_depth=0.5, hold_s=0.5)
    tracker.observe(touch(7, "down", 0.9, "hold"), 0.0)
    assert not tracker.active(31.0)
