"""Stream slots (MJPEG, speech): a bounded number per client, per address and in total.

Each stream holds a coroutine, a socket and up to a send buffer of frames;
without a per-client cap one headset (or a page reloaded in a loop) could
take every slot and nobody else would get video. Client ids are free to
pick, so one address (a device, whatever ids it sends) has a cap of its own,
below the total ([http] max_streams_per_address): another device always finds
a slot.
"""

from __future__ import annotations

from collections import Counter

from feelium.http.clients import address_of


class SlotsFull(Exception):
    """No slot for this client; the message says which limit was reached."""


class StreamSlots:
    """Counts open streams per client; :meth:`acquire` refuses above either limit."""

    def __init__(self, total: int, per_client: int, what: str = "video streams", per_address: int | None = None) -> None:
        if total < 1 or per_client < 1 or (per_address is not None and per_address < 1):
            raise ValueError("stream limits must be at least 1")
        self.what = what  # named in the refusal: "video streams", "speech streams"
        self.total = total
        self.per_client = per_client
        self.per_address = total if per_address is None else per_address
        self._open: Counter[str] = Counter()
        self._by_address: Counter[str] = Counter()
        self.refused = 0

    @property
    def in_use(self) -> int:
        return sum(self._open.values())

    def held_by(self, client: str) -> int:
        return self._open[client]

    def acquire(self, client: str) -> None:
        """Take a slot for ``client`` or raise :class:`SlotsFull`."""
        if self._open[client] >= self.per_client:
            self.refused += 1
            raise SlotsFull(f"this client already has {self._open[client]} {self.what} (at most {self.per_client})")
        address = address_of(client)
        if self._by_address[address] >= self.per_address:
            self.refused += 1
            raise SlotsFull(f"this address already has {self._by_address[address]} {self.what} (at most {self.per_address})")
        if self.in_use >= self.total:
            self.refused += 1
            raise SlotsFull(f"all {self.total} {self.what} are in use")
        self._open[client] += 1
        self._by_address[address] += 1

    def release(self, client: str) -> None:
        """Give back a slot taken by :meth:`acquire`."""
        if self._open[client] <= 0:
            raise ValueError(f"client {client!r} holds no stream slot")
        self._open[client] -= 1
        if not self._open[client]:
            del self._open[client]
        address = address_of(client)
        self._by_address[address] -= 1
        if not self._by_address[address]:
            del self._by_address[address]
