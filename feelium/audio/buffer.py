"""The speaker's queue: bounded in milliseconds, so a burst of late packets never becomes a lasting delay.

When the wearer's audio arrives faster than the speaker plays it (network
bursts, or the headset's clock running a little fast against the sound card's),
a plain FIFO would grow without end and the wearer's voice would lag more and
more. This queue keeps at most ``max_ms``; beyond that it drops the oldest
audio and counts it, so latency stays bounded and drift never accumulates.
"""

from __future__ import annotations

from collections import deque


class PlaybackBuffer:
    """PCM16 mono bytes waiting for the speaker."""

    def __init__(self, rate: int, max_ms: int) -> None:
        if rate <= 0 or max_ms <= 0:
            raise ValueError("rate and max_ms must be positive")
        self.rate = rate
        self.max_bytes = 2 * rate * max_ms // 1000
        self._chunks: deque[bytes] = deque()
        self._size = 0
        self.dropped_bytes = 0

    def __len__(self) -> int:
        return self._size

    @property
    def buffered_ms(self) -> float:
        return 1000.0 * self._size / (2 * self.rate)

    def push(self, pcm: bytes) -> None:
        """Queue ``pcm`` (whole samples), dropping the oldest audio beyond ``max(max_ms, len(pcm))``."""
        pcm = pcm[: len(pcm) - len(pcm) % 2]
        if not pcm:
            return
        self._chunks.append(pcm)
        self._size += len(pcm)
        limit = max(self.max_bytes, len(pcm))
        while self._size > limit:
            excess = self._size - limit
            head = self._chunks[0]
            if len(head) <= excess:
                self._chunks.popleft()
                self._size -= len(head)
                self.dropped_bytes += len(head)
            else:
                cut = excess + excess % 2
                self._chunks[0] = head[cut:]
                self._size -= cut
                self.dropped_bytes += cut

    def pop(self, max_bytes: int) -> bytes:
        """Up to ``max_bytes`` (rounded down to whole samples) of the oldest audio."""
        want = max_bytes - max_bytes % 2
        out: list[bytes] = []
        while want > 0 and self._chunks:
            head = self._chunks[0]
            if len(head) <= want:
                out.append(self._chunks.popleft())
                want -= len(head)
                self._size -= len(head)
            else:
                out.append(head[:want])
                self._chunks[0] = head[want:]
                self._size -= want
                want = 0
        return b"".join(out)
