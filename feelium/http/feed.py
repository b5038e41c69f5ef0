"""Fills the event ring from the bus and wakes every waiting long-poll, SSE and WebSocket client."""

from __future__ import annotations

import asyncio
from typing import Any

from feelium.bus import EventBus, Subscription
from feelium.http.ring import WIRE_TYPES, Catchup, EventRing


class EventFeed:
    """One bus subscription feeding one ring; clients await :meth:`wait_after`."""

    def __init__(self, bus: EventBus, capacity: int, epoch: str) -> None:
        self.ring = EventRing(capacity, epoch)
        self._bus = bus
        self._sub: Subscription[Any] | None = None
        self._changed = asyncio.Event()
        self.bad_events = 0

    def start(self) -> None:
        """Subscribe (call on the loop before events should be seen)."""
        if self._sub is None:
            self._sub = self._bus.subscribe(tuple(WIRE_TYPES), maxsize=max(64, self.ring_capacity))

    @property
    def ring_capacity(self) -> int:
        return self.ring._items.maxlen or 1

    def add(self, event: Any) -> None:
        """Number ``event`` into the ring and wake the waiters; a bad event is counted and skipped."""
        try:
            self.ring.append(event)
        except Exception:
            self.bad_events += 1
            return
        self._changed.set()
        self._changed = asyncio.Event()

    async def pump(self) -> None:
        """Move bus events into the ring until cancelled."""
        self.start()
        assert self._sub is not None
        while True:
            event = await self._sub.get()
            if event is not None:
                self.add(event)
                for more in self._sub.drain():
                    self.add(more)

    def close(self) -> None:
        if self._sub is not None:
            self._sub.close()
            self._sub = None

    async def wait_after(self, seq: int, timeout: float, epoch: str | None = None) -> Catchup:
        """Events after ``seq`` of ``epoch``, waiting up to ``timeout`` seconds for the first one."""
        catchup = self.ring.after(seq, epoch)
        if catchup.events or catchup.reset or timeout <= 0:
            return catchup
        changed = self._changed
        try:
            async with asyncio.timeout(timeout):
                await changed.wait()
        except asyncio.TimeoutError:
            pass
        return self.ring.after(seq, epoch)

    def health(self) -> dict[str, Any]:
        sub = self._sub
        return {
            "last_seq": self.ring.last_seq,
            "epoch": self.ring.epoch,
            "bus_dropped": sub.dropped if sub is not None else 0,
            "bad_events": self.bad_events,
        }
