"""A byte link that misbehaves on a schedule: stalls, reply lag and unplugged adapters.

Wraps any :class:`ByteLink` (usually :class:`~feelium.flight.sim_board.SimSerial`)
so the client's reply matching and resynchronisation, and the flight loop
around it, can be tried against what real boards and USB adapters do:

- a *stall* holds every byte written between ``start_s`` and ``end_s`` and
  makes nothing readable; at its end everything held reaches the board at
  once, so the board answers the whole backlog in one flood;
- a *lag* makes the bytes the inner link produces readable only ``lag_s``
  after they were produced (in order: a serial line never reorders);
- a *drop* makes every call raise :class:`OSError` while it lasts, and a
  link cannot be opened then, like an unplugged USB adapter;
- ``inject`` puts noise on the line.

On a manual clock nothing would pass the time while the client waits for
lagged bytes, so an optional ``sleep`` lets simulated time pass when a read
finds nothing, as a pyserial read blocks until a byte or its timeout.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from feelium.flight.transport import ByteLink

MIN_WAIT_S = 1e-4  # shortest simulated blocking read: about one byte at 115200 baud


@dataclass(frozen=True)
class Window:
    """A time interval on the link's clock, start included, end excluded."""

    start_s: float
    end_s: float

    def covers(self, t: float) -> bool:
        return self.start_s <= t < self.end_s


@dataclass(frozen=True)
class LinkFaults:
    """The fault schedule: stall and drop windows and a constant reply lag."""

    stalls: tuple[Window, ...] = ()
    drops: tuple[Window, ...] = ()
    lag_s: float = 0.0

    def stall_at(self, t: float) -> Window | None:
        return next((w for w in self.stalls if w.covers(t)), None)

    def dropped(self, t: float) -> bool:
        return any(w.covers(t) for w in self.drops)


class FaultyLink:
    """A :class:`ByteLink` over ``inner`` that applies ``faults`` on ``clock``; ``faults`` may be replaced at any time."""

    def __init__(
        self,
        inner: ByteLink,
        clock: Callable[[], float],
        faults: LinkFaults = LinkFaults(),
        sleep: Callable[[float], None] | None = None,
        read_timeout_s: float = 0.005,
    ) -> None:
        if faults.dropped(clock()):
            raise OSError("motor board link unplugged")
        self.inner = inner
        self.clock = clock
        self.faults = faults
        self.sleep = sleep
        self.read_timeout_s = read_timeout_s
        self.held = bytearray()  # written during a stall, not delivered yet
        self._incoming: deque[tuple[float, bytes]] = deque()  # (readable from, bytes), oldest first

    # ---- ByteLink ----
    @property
    def in_waiting(self) -> int:
        return self._ready_bytes(self._now())

    def write(self, data: bytes) -> int:
        now = self._now()
        if self.faults.stall_at(now):
            self.held += data
        else:
            self._deliver(bytes(data), now)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        now = self._now()
        if not self._ready_bytes(now) and self.sleep is not None:
            self.sleep(self._wait_s(now))
            now = self._now()
        return self._take(min(size, self._ready_bytes(now)))

    def close(self) -> None:
        self.inner.close()

    def inject(self, noise: bytes) -> None:
        """Noise on the line (garbage, a torn frame): readable at once, behind whatever is already queued."""
        self._incoming.append((self.clock(), bytes(noise)))

    # ---- the faults ----
    def _now(self) -> float:
        """The clock, after the checks every call makes: a drop raises, a stall that ended releases its backlog."""
        now = self.clock()
        if self.faults.dropped(now):
            raise OSError("motor board link unplugged")
        if self.held and not self.faults.stall_at(now):
            held, self.held = bytes(self.held), bytearray()
            self._deliver(held, now)
        return now

    def _deliver(self, data: bytes, now: float) -> None:
        """Hand bytes to the board and queue what it answers, readable after the lag."""
        self.inner.write(data)
        waiting = self.inner.in_waiting
        if waiting:
            self._incoming.append((round(now + self.faults.lag_s, 9), self.inner.read(waiting)))

    def _ready_bytes(self, now: float) -> int:
        """Bytes readable now: nothing during a stall, else the queued chunks that are due, in order."""
        if self.faults.stall_at(now):
            return 0
        ready = 0
        for due, chunk in self._incoming:
            if due > now:
                break
            ready += len(chunk)
        return ready

    def _wait_s(self, now: float) -> float:
        """How long a blocking read waits: until the next byte is due, at most the read timeout."""
        stall = self.faults.stall_at(now)
        due = stall.end_s if stall else (self._incoming[0][0] if self._incoming else float("inf"))
        return max(MIN_WAIT_S, min(self.read_timeout_s, due - now))

    def _take(self, size: int) -> bytes:
        out = bytearray()
        while len(out) < size:
            due, chunk = self._incoming.popleft()
            need = size - len(out)
            out += chunk[:need]
            if len(chunk) > need:
                self._incoming.appendleft((due, chunk[need:]))
        return bytes(out)
