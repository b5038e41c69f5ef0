"""The event ring: what long-poll, SSE and WebSocket clients all read, with one wire format.

Every event the headset may see gets a monotonic sequence number and is kept
in a bounded ring, so a client that reconnects asks for ``after=SEQ`` and
catches up; a client that fell further behind than the ring holds (or that
remembers a sequence from an earlier daemon run) is told ``reset`` and must
re-read the state instead of silently missing touches. Pure: no clock, no I/O.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

from feelium.events import InteractionEvent, PresenceEvent, TouchEvent, WearerAction

# The ``type`` tag of each event class on the wire (the one place it is defined).
WIRE_TYPES: dict[type, str] = {
    TouchEvent: "touch",
    PresenceEvent: "presence",
    InteractionEvent: "interaction",
    WearerAction: "wearer_action",
}


def wire_type(event: object) -> str:
    """The ``type`` tag of ``event``; unknown classes get their lower-cased class name."""
    return WIRE_TYPES.get(type(event), type(event).__name__.lower())


def envelope(seq: int, event: Any) -> dict[str, Any]:
    """The one wire form of an event: ``{"seq": n, "type": "touch", "event": {...}}``."""
    return {"seq": seq, "type": wire_type(event), "event": event.to_json()}


@dataclass(frozen=True)
class Catchup:
    """What a client reading after ``after`` gets: the events, the newest seq, and whether it lost some."""

    events: list[dict[str, Any]]
    last_seq: int
    reset: bool


class EventRing:
    """Bounded, sequence-numbered store of wire envelopes."""

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError("capacity must be at least 1")
        self._items: deque[dict[str, Any]] = deque(maxlen=capacity)
        self.last_seq = 0

    def append(self, event: Any) -> dict[str, Any]:
        """Number ``event`` and keep its envelope (the oldest falls out when full)."""
        self.last_seq += 1
        item = envelope(self.last_seq, event)
        self._items.append(item)
        return item

    @property
    def first_seq(self) -> int:
        """The oldest sequence still held (``last_seq + 1`` when empty)."""
        return self._items[0]["seq"] if self._items else self.last_seq + 1

    def after(self, seq: int) -> Catchup:
        """Events with a sequence above ``seq``.

        ``reset`` is true when events after ``seq`` have already fallen out
        of the ring, or when ``seq`` lies in the future (an earlier daemon
        run); the client then gets everything held and should re-read state.
        """
        if seq > self.last_seq or seq < self.first_seq - 1:
            return Catchup(list(self._items), self.last_seq, reset=True)
        start = seq - self.first_seq + 1
        items = [self._items[i] for i in range(start, len(self._items))]
        return Catchup(items, self.last_seq, reset=False)
