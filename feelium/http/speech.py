"""Blimp-to-wearer speech: the newest captured chunks, numbered, for the headset to fetch as WAV or stream.

Kept bounded in milliseconds: a headset that polls late skips ahead to the
newest audio instead of hearing the room with a growing delay. The feed listens
on the bus (:meth:`~feelium.bus.EventBus.listen`): a chunk is numbered inside the
microphone's publish, and only the clients waiting for it wake.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Callable

from feelium.events import SpeechOut
from feelium.bus import EventBus


class SpeechFeed:
    """Numbered :class:`SpeechOut` chunks, at most ``keep_ms`` of them."""

    def __init__(self, bus: EventBus, keep_ms: int) -> None:
        self._bus = bus
        self.keep_ms = keep_ms
        self._chunks: deque[tuple[int, SpeechOut]] = deque()
        self._ms = 0.0
        self.last_seq = 0
        self._unlisten: Callable[[], None] | None = None
        self._changed = asyncio.Event()

    def add(self, chunk: SpeechOut) -> None:
        self.last_seq += 1
        self._chunks.append((self.last_seq, chunk))
        self._ms += _ms(chunk)
        while self._ms > self.keep_ms and len(self._chunks) > 1:
            self._ms -= _ms(self._chunks.popleft()[1])
        self._changed.set()
        self._changed = asyncio.Event()

    def after(self, seq: int) -> tuple[list[SpeechOut], int]:
        """Chunks numbered above ``seq`` (all held ones when ``seq`` is stale or from the future)."""
        return [c for _, c in self.numbered_after(seq)], self.last_seq

    def numbered_after(self, seq: int) -> list[tuple[int, SpeechOut]]:
        """``(number, chunk)`` above ``seq``, as :meth:`after`; the stream puts the numbers in its frames."""
        if seq > self.last_seq:
            seq = 0
        return [(s, c) for s, c in self._chunks if s > seq]

    async def wait_numbered_after(self, seq: int, timeout: float) -> list[tuple[int, SpeechOut]]:
        """:meth:`numbered_after`, waiting up to ``timeout`` seconds for the first chunk."""
        chunks = self.numbered_after(seq)
        if chunks or timeout <= 0:
            return chunks
        changed = self._changed
        try:
            async with asyncio.timeout(timeout):
                await changed.wait()
        except asyncio.TimeoutError:
            pass
        return self.numbered_after(seq)

    async def wait_after(self, seq: int, timeout: float) -> tuple[list[SpeechOut], int]:
        chunks = await self.wait_numbered_after(seq, timeout)
        return [c for _, c in chunks], self.last_seq

    def start(self) -> None:
        """Number every chunk published from now on (call on the loop)."""
        if self._unlisten is None:
            self._unlisten = self._bus.listen([SpeechOut], self.add)

    def close(self) -> None:
        if self._unlisten is not None:
            self._unlisten()
            self._unlisten = None


def _ms(chunk: SpeechOut) -> float:
    return 1000.0 * len(chunk.pcm) / (2 * chunk.rate) if chunk.rate > 0 else 0.0
