"""Counting the event loop's wake-ups, shared by the benchmarks that report callbacks per unit of work."""

from __future__ import annotations

import asyncio


class CallbackCount:
    """Counts the event loop's callbacks (every ``asyncio`` handle run) while installed: the loop's wake-ups."""

    def __init__(self) -> None:
        self.calls = 0
        self._original = asyncio.events.Handle._run

    def __enter__(self) -> "CallbackCount":
        original, counter = self._original, self

        def counted(handle: asyncio.events.Handle) -> None:
            counter.calls += 1
            original(handle)

        asyncio.events.Handle._run = counted  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: object) -> None:
        asyncio.events.Handle._run = self._original  # type: ignore[method-assign]
