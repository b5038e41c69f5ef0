"""When to stop fighting: a firm touch or a hug in progress makes the controller soft.

A partner pressing a palm into the blimp, or hugging it, should feel it
yield, not push back; and the wearer's motion commands must not drive it
into them. This pure tracker turns the touch and interaction events into a
yes/no for "soften now", from the events alone (time is an input).
"""

from __future__ import annotations

from feelium.events import InteractionEvent, TouchEvent

STUCK_CONTACT_S = 30.0  # a contact whose "up" was lost stops counting after this


class SoftenTracker:
    """Firm contacts in progress and hugs in progress, plus a short grace period after the last one."""

    def __init__(self, firm_depth: float, hold_s: float) -> None:
        self.firm_depth = firm_depth
        self.hold_s = hold_s
        self._contacts: dict[int, float] = {}  # touch id -> time it became firm
        self._hug_since: float | None = None
        self._soft_until = float("-inf")
        self.softened_events = 0

    def observe(self, event: object, now: float) -> None:
        if isinstance(event, TouchEvent):
            self._observe_touch(event, now)
        elif isinstance(event, InteractionEvent) and event.name == "hug":
            if event.phase == "end":
                self._hug_since = None
                self._soft_until = max(self._soft_until, now + self.hold_s)
            else:
                self._hug_since = self._hug_since if self._hug_since is not None else now
                self.softened_events += 1

    def _observe_touch(self, event: TouchEvent, now: float) -> None:
        if event.phase == "up":
            if self._contacts.pop(event.id, None) is not None:
                self._soft_until = max(self._soft_until, now + self.hold_s)
            return
        firm = event.kind == "hold" or (event.depth == event.depth and event.depth >= self.firm_depth)
        if firm:
            self._contacts.setdefault(event.id, now)
            self.softened_events += 1

    def active(self, now: float) -> bool:
        for contact_id, since in list(self._contacts.items()):
            if now - since > STUCK_CONTACT_S:
                del self._contacts[contact_id]
        if self._hug_since is not None and now - self._hug_since > STUCK_CONTACT_S:
            self._hug_since = None
        return bool(self._contacts) or self._hug_since is not None or now < self._soft_until
