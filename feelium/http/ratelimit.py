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

from feelium.http.clients import address_of
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

    def has_token(self, now: float) -> bool:
        """Whether :meth:`take` would succeed now, without taking (to refuse a big body before reading it)."""
        self._refill(now)
        return self._tokens >= 1.0

    def retry_after(self, now: float) -> float:
        """Seconds until the next token."""
        self._refill(now)
        return max(0.0, (1.0 - self._tokens) / self.rate)


class ClientBuckets:
    """A :class:`TokenBucket` per client key, at most ``max_clients`` remembered; with ``clients_per_address``,
    also one per address at that many times the rate and burst, charged with every request of its clients
    (an id is free to pick, an address is not)."""

    def __init__(self, rate: float, burst: int, max_clients: int = 256, clients_per_address: int | None = None) -> None:
        if max_clients < 1:
            raise ValueError("max_clients must be at least 1")
        if clients_per_address is not None and clients_per_address < 1:
            raise ValueError("clients_per_address must be at least 1")
        TokenBucket(rate, burst, 0.0)  # validate the parameters now, not at the first request
        self.rate = rate
        self.burst = burst
        self.max_clients = max_clients
        self.clients_per_address = clients_per_address
        self._buckets: OrderedDict[str, TokenBucket] = OrderedDict()
        self.rejected = 0

    def _bucket(self, key: str, now: float, scale: int = 1) -> TokenBucket:
        bucket = self._buckets.get(key)
        if bucket is None:
            if len(self._buckets) >= self.max_clients:
                self._buckets.popitem(last=False)
            bucket = self._buckets[key] = TokenBucket(self.rate * scale, self.burst * scale, now)
        else:
            self._buckets.move_to_end(key)
        return bucket

    def _buckets_of(self, client: str, now: float) -> list[TokenBucket]:
        buckets = [self._bucket(client, now)]
        address = address_of(client)
        if self.clients_per_address is not None and address != client:
            buckets.append(self._bucket(f"address {address}", now, self.clients_per_address))
        return buckets

    def take(self, client: str, now: float) -> bool:
        """Charge one request to ``client`` (and its address); ``False`` when either bucket is empty."""
        buckets = self._buckets_of(client, now)
        if all(b.has_token(now) for b in buckets):
            for bucket in buckets:
                bucket.take(now)
            return True
        self.rejected += 1
        return False

    def has_token(self, client: str, now: float) -> bool:
        """Whether ``client`` could be charged now (nothing is taken)."""
        return all(b.has_token(now) for b in self._buckets_of(client, now))

    def retry_after(self, client: str, now: float) -> float:
        """Seconds until ``client`` may send again."""
        return max(b.retry_after(now) for b in self._buckets_of(client, now))

    def __len__(self) -> int:
        return len(self._buckets)


def charge(limit: ClientBuckets, client: str, now: float, what: str) -> None:
    """Take one request from ``client``'s bucket or answer 429 with ``Retry-After``."""
    if not limit.take(client, now):
        wait = limit.retry_after(client, now)
        raise ApiError(
            429,
            f"{what} are limited to {limit.rate:g}/s per client"
            + (f" and {limit.rate * limit.clients_per_address:g}/s per address" if limit.clients_per_address else "")
            + f"; retry in {wait:.2f} s",
            headers={"Retry-After": str(max(1, math.ceil(wait)))},
        )
