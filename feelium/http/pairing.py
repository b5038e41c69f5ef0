"""Pairing: the headset gets the token by typing a short code instead of carrying the token in a URL.

``feelium pair`` (or any client that already holds the token) asks the daemon
for a code; the wearer types it into the headset app, which exchanges it at
``POST /pair`` for the token. A code works once and only for ``ttl_s``; a new
code replaces the old one, and after ``max_failures`` wrong guesses the code
is void, so 8 random digits leave a guesser at most a 5 in 10^8 chance. Pure:
times are inputs (the daemon clock); randomness comes from :mod:`secrets`.
"""

from __future__ import annotations

import hmac
import secrets
from dataclasses import dataclass

CODE_DIGITS = 8


def normalise(code: str) -> str:
    """The digits of a typed code (``1234-5678``, ``1234 5678`` and ``12345678`` are the same code)."""
    return "".join(ch for ch in code if ch.isascii() and ch.isdigit())


@dataclass
class _Pending:
    digits: str
    expires_at: float
    failures: int = 0


class PairingCodes:
    """At most one outstanding code, valid once, until it expires or is guessed at too often."""

    def __init__(self, ttl_s: float, max_failures: int = 5) -> None:
        self.ttl_s = ttl_s
        self.max_failures = max_failures
        self._pending: _Pending | None = None
        self.paired = 0
        self.refused = 0

    def issue(self, now: float) -> str:
        """A new code (``1234-5678``), replacing any outstanding one."""
        digits = "".join(secrets.choice("0123456789") for _ in range(CODE_DIGITS))
        self._pending = _Pending(digits, now + self.ttl_s)
        return f"{digits[:4]}-{digits[4:]}"

    def redeem(self, code: str, now: float) -> bool:
        """Whether ``code`` is the outstanding code, unexpired; a match uses it up, a miss counts against it."""
        pending = self._pending
        if pending is None or now >= pending.expires_at:
            self._pending = None
            self.refused += 1
            return False
        if hmac.compare_digest(normalise(code).encode(), pending.digits.encode()):
            self._pending = None
            self.paired += 1
            return True
        pending.failures += 1
        if pending.failures >= self.max_failures:
            self._pending = None
        self.refused += 1
        return False

    def remaining_s(self, now: float) -> float | None:
        """Seconds the outstanding code stays valid, or ``None``."""
        pending = self._pending
        return None if pending is None or now >= pending.expires_at else pending.expires_at - now
