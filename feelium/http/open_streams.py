"""Long-lived streams (MJPEG, SSE, WebSockets) and the token each was opened with, so a rotation ends them.

A request is authenticated once, when it arrives; a stream then lives for
hours. Without this registry a device whose token was rotated away (lost,
revoked) would keep watching, listening and steering over the sockets it
already holds. The link checks every second (the token file itself is
re-read at most once a second) and closes each stream whose token no longer
matches.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from aiohttp import web

CHECK_EVERY_S = 1.0
POLICY_VIOLATION = 1008


def ws_closer(ws: web.WebSocketResponse) -> Callable[[], None]:
    """Close ``ws`` with 1008 "token rotated" (a clean close the client can tell from a network drop)."""
    pending: set[asyncio.Task[Any]] = set()

    def close() -> None:
        task = asyncio.ensure_future(ws.close(code=POLICY_VIOLATION, message=b"token rotated"))
        pending.add(task)
        task.add_done_callback(pending.discard)

    return close


def transport_closer(request: web.Request) -> Callable[[], None]:
    """Cut a plain HTTP stream (MJPEG, SSE) off: there is no close message to send."""

    def close() -> None:
        if request.transport is not None:
            request.transport.abort()

    return close


class OpenStreams:
    """The open streams, each with its presented token and how to close it."""

    def __init__(self) -> None:
        self._open: dict[int, tuple[str | None, Callable[[], None]]] = {}
        self._next = 0
        self.closed_for_rotation = 0

    @contextmanager
    def held(self, token: str | None, close: Callable[[], None]) -> Iterator[None]:
        """Register a stream for as long as the ``with`` block runs."""
        key = self._next
        self._next += 1
        self._open[key] = (token, close)
        try:
            yield
        finally:
            self._open.pop(key, None)

    def close_revoked(self, still_valid: Callable[[str | None], bool]) -> int:
        """Close every stream whose token ``still_valid`` rejects; how many were closed."""
        closed = 0
        for key, (token, close) in list(self._open.items()):
            if not still_valid(token):
                self._open.pop(key, None)
                close()
                closed += 1
        self.closed_for_rotation += closed
        return closed

    def __len__(self) -> int:
        return len(self._open)
