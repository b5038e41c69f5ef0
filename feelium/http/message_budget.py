"""How many messages a client may send on one WebSocket: a client flooding its socket is disconnected.

Every message a client sends costs the event loop a parse and often a reply,
whether it is then refused (429, 400) or not; a refusal is no protection
against the work. aiohttp hands over messages already buffered without
yielding to the loop, so a flood also starves every other task (the cameras,
another client's stop). Each socket therefore has a budget well above any
honest use (motion refreshed at 20 Hz, speech chunks at their own limit);
a socket over it is cut off (no close handshake: waiting for the client's
reply, the loop would go on parsing the flood), and the reader yields to
the loop after each message.
"""

from __future__ import annotations

from aiohttp import WSMsgType

from feelium.http.ratelimit import TokenBucket

# What a client's messages cost: data, and the control frames a flood can be made of just as well (the
# sockets run with autoping off, so pings and pongs reach the reader and are answered there).
BUDGETED = frozenset({WSMsgType.TEXT, WSMsgType.BINARY, WSMsgType.PING, WSMsgType.PONG})


class MessageBudget:
    """``rate`` messages per second with a burst of ``burst`` on one socket."""

    def __init__(self, rate: float, burst: int, now: float) -> None:
        self._bucket = TokenBucket(rate, burst, now)
        self.rate = rate

    def allows(self, now: float) -> bool:
        return self._bucket.take(now)
