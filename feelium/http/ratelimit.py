"""Token buckets, one per client: time is an input, so the rules are testable without a clock.

Each client (see :mod:`feelium.http.clients`) gets its own bucket, so a
headset that floods can only exhaust its own allowance, never another
client's. The number of buckets is bounded: the least recently used one is
forgotten when a new client arrives at the limit (a forgotten client comes
back with a full bucket, which costs at most one burst).
"""

from __future__ import annotations

import math
from collections import OrderedDict

from feelium.http.errors import ApiError


class TokenBucket:
    """``rate`` tokens per second up to ``burst``; each accepted request takes one."""

    def __init__(self, rate: float, burst: int, now: float) -> None:
        if not (rate > 0 and math.isfinite(rate)) or burst < 1:
            raise ValueError("rate must be positive and finite, burst at least 1")
        self.rate = rate
        self.burst = float(burst)
        self._tokens = float(burst)
        self._at = now
        self.rejected = 0

    def _refill(self, now: float) -> None:
        if now > self._at:
            self._tokens = min(self.burst, self._tokens + (now - self._at) * self.rate)
            self._at = now

    def take(self, now: float) -> bool:
        """Take a token if one is there; a clock that steps back never refills."""
        self._refill(now)
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        self.rejected += 1
        return False

    def retry_after(self, now: float) -> float:
        """Seconds until the next token."""
        self._refill(now)
        return max(0.0, (1.0 - self._tokens) / self.rate)


class ClientBuckets:
    """A :class:`TokenBucket` per client key, at most ``max_clients`` remembered."""

    def __init__(self, rate: float, burst: int, max_clients: int = 256) -> None:
        if max_clients < 1:
            raise ValueError("max_clients must be at least 1")
        TokenBucket(rate, burst, 0.0)  # validate the parameters now, not at the first request
        self.rate = rate
        self.burst = burst
        self.max_clients = max_clients
        self._buckets: OrderedDict[str, TokenBucket] = OrderedDict()
        self.rejected = 0

    def _bucket(self, client: str, now: float) -> TokenBucket:
        bucket = self._buckets.get(client)
        if bucket is None:
            if len(self._buckets) >= self.max_clients:
                self._buckets.popitem(last=False)
            bucket = self._buckets[client] = TokenBucket(self.rate, self.burst, now)
        else:
            self._buckets.move_to_end(client)
        return bucket

    def take(self, client: str, now: float) -> bool:
        """Charge one request to ``client``; ``False`` when its bucket is empty."""
        if self._bucket(client, now).take(now):
            return True
        self.rejected += 1
        return False

    def retry_after(self, client: str, now: float) -> float:
        """Seconds until ``client`` may send again."""
        bucket = self._buckets.get(client)
        return 0.0 if bucket is None else bucket.retry_after(now)

    def __len__(self) -> int:
        return len(self._buckets)


def charge(limit: ClientBuckets, client: str, now: float, what: str) -> None:
    """Take one request from ``client``'s bucket or answer 429 with ``Retry-After``."""
    if not limit.take(client, now):
        wait = limit.retry_after(client, now)
        raise ApiError(
            429,
            f"{what} are limited to {limit.rate:g}/s per client; retry in {wait:.2f} s",
            headers={"Retry-After": str(max(1, math.ceil(wait)))},
        )
