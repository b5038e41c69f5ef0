"""Small services for supervisor tests: one that ticks, one that crashes, one that will not stop, one with a heartbeat."""

from __future__ import annotations

import asyncio
from typing import Any


class TickingService:
    def __init__(self, name: str = "ticker", stop_order: int = 50, log: list[str] | None = None) -> None:
        self.name = name
        self.stop_order = stop_order
        self.ticks = 0
        self.log = log if log is not None else []
        self._stopping = asyncio.Event()

    async def run(self) -> None:
        while not self._stopping.is_set():
            self.ticks += 1
            await asyncio.sleep(0.005)

    async def stop(self) -> None:
        self.log.append(self.name)
        self._stopping.set()

    def health(self) -> dict[str, Any]:
        return {"ticks": self.ticks}


class CrashingService(TickingService):
    """Crashes ``crashes`` times shortly after starting, then runs."""

    def __init__(self, crashes: int, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.crashes = crashes
        self.runs = 0

    async def run(self) -> None:
        self.runs += 1
        if self.runs <= self.crashes:
            await asyncio.sleep(0.001)
            raise RuntimeError(f"boom {self.runs}")
        await super().run()


class StubbornService(TickingService):
    """stop() hangs and run() ignores it: only cancellation ends it."""

    async def stop(self) -> None:
        self.log.append(self.name)
        await asyncio.sleep(3600)


class HeartbeatService(TickingService):
    """A vital (flight-loop-like) service whose heartbeat stops while ``frozen`` is set."""

    vital = True

    def __init__(self, clock: Any, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.clock = clock
        self.frozen = False
        self.heartbeat_at: float | None = None

    async def run(self) -> None:
        while not self._stopping.is_set():
            if not self.frozen:
                self.heartbeat_at = self.clock()
            await asyncio.sleep(0.005)

    def health(self) -> dict[str, Any]:
        return {"heartbeat_at": self.heartbeat_at}
