"""Who steers the blimp: one controlling client at a time, taken over explicitly, lapsing when it goes quiet.

Two headsets (or a headset and a browser tab) that both send motion would
fight over the blimp, each command undoing the other's. The lease makes
steering exclusive: the first client to move holds it, its motion renews it,
and another client's motion is refused until it asks to take over (or the
holder has been quiet for ``lease_s``). Stopping is never refused: a stop
from any client applies at once and hands that client the lease, so a
stop from a bystander sticks instead of being undone by the holder's next
refresh of its held command.

Pure: times are inputs (the daemon clock, seconds).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Holder:
    """The controlling client and when its lease lapses unless renewed."""

    client: str
    expires_at: float


class ControlLease:
    """The motion lease of one blimp."""

    def __init__(self, lease_s: float) -> None:
        if not (math.isfinite(lease_s) and lease_s > 0):
            raise ValueError(f"lease_s must be positive and finite, got {lease_s}")
        self.lease_s = lease_s
        self._holder: Holder | None = None
        self.takeovers = 0
        self.refused = 0

    def holder(self, now: float) -> Holder | None:
        """The controlling client at ``now``, or ``None`` once its lease lapsed."""
        if self._holder is not None and now >= self._holder.expires_at:
            self._holder = None
        return self._holder

    def claim(self, client: str, now: float, take_over: bool = False) -> Holder | None:
        """Renew or take the lease for ``client``; returns the other holder when refused, else ``None``."""
        current = self.holder(now)
        if current is not None and current.client != client:
            if not take_over:
                self.refused += 1
                return current
            self.takeovers += 1
        self._holder = Holder(client, now + self.lease_s)
        return None

    def stopped_by(self, client: str, now: float) -> None:
        """A stop from ``client``: it holds the lease from now on (a stop is never refused)."""
        self._holder = Holder(client, now + self.lease_s)
