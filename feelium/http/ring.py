"""The event ring: what long-poll, SSE and WebSocket clients all read, with one wire format.

Every event the headset may see gets a monotonic sequence number and is kept
in a bounded ring, so a client that reconnects asks for ``after=SEQ`` and
catches up. Numbers restart with the daemon, so every ring has an ``epoch``
(a random id per run) carried in each envelope and in the resume token
``EPOCH:SEQ``. A client that fell further behind than the ring holds, or that
resumes with a token of another epoch (the daemon restarted), is told
``reset``: it gets the current state and then only new events, never the old
ones replayed with numbers that go backwards. Pure: no clock, no I/O.
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


def envelope(seq: int, event: Any, epoch: str) -> dict[str, Any]:
    """The one wire form of an event: ``{"seq": n, "epoch": "...", "type": "touch", "event": {...}}``."""
    return {"seq": seq, "epoch": epoch, "type": wire_type(event), "event": event.to_json()}


def resume_token(epoch: str, seq: int) -> str:
    """Where a client resumes: ``EPOCH:SEQ`` (the SSE ``id``, and what ``?after=`` takes)."""
    return f"{epoch}:{seq}"


def parse_resume(text: str, max_seq: int) -> tuple[str | None, int]:
    """``EPOCH:SEQ`` or a bare ``SEQ`` (no epoch: taken as the current run's) -> ``(epoch, seq)``; ValueError if neither."""
    epoch, sep, number = text.rpartition(":")
    if sep and not epoch:
        raise ValueError("empty epoch")
    if not number.isascii() or not number.isdigit() or len(number) > 20 or int(number) > max_seq:
        raise ValueError(f"sequence must be an integer within 0..{max_seq}")
    return (epoch if sep else None), int(number)


@dataclass(frozen=True)
class Catchup:
    """What a client reading after ``after`` gets: the events, the newest seq, and whether it lost some."""

    events: list[dict[str, Any]]
    last_seq: int
    reset: bool


class EventRing:
    """Bounded, sequence-numbered store of wire envelopes."""

    def __init__(self, capacity: int, epoch: str) -> None:
        if capacity < 1:
            raise ValueError("capacity must be at least 1")
        self._items: deque[dict[str, Any]] = deque(maxlen=capacity)
        self.last_seq = 0
        self.epoch = epoch

    def append(self, event: Any) -> dict[str, Any]:
        """Number ``event`` and keep its envelope (the oldest falls out when full)."""
        self.last_seq += 1
        item = envelope(self.last_seq, event, self.epoch)
        self._items.append(item)
        return item

    @property
    def first_seq(self) -> int:
        """The oldest sequence still held (``last_seq + 1`` when empty)."""
        return self._items[0]["seq"] if self._items else self.last_seq + 1

    def after(self, seq: int, epoch: str | None = None) -> Catchup:
        """Events with a sequence above ``seq`` of ``epoch`` (``None``: this ring's).

        ``reset`` is true when events after ``seq`` have already fallen out of the ring, when ``seq`` lies
        in the future or ``epoch`` is another run's (the daemon restarted); a reset carries no events (the
        client re-reads the state and continues from ``last_seq``), so nothing is replayed out of order.
        """
        if (epoch is not None and epoch != self.epoch) or seq > self.last_seq or seq < self.first_seq - 1:
            return Catchup([], self.last_seq, reset=True)
        start = seq - self.first_seq + 1
        items = [self._items[i] for i in range(start, len(self._items))]
        return Catchup(items, self.last_seq, reset=False)
