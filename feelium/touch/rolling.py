"""Rolling minimum over a window of time (not of frames), amortised O(1) per sample.

A monotonic deque: each new value removes every older value that is not
smaller (they can never be the minimum again), and values older than the
window fall off the front. Keyed by timestamps, so dropped frames and jitter
shorten nothing: the window is always the last ``window_s`` of camera time.
"""

from __future__ import annotations

from collections import deque


class RollingMin:
    """Minimum of the values pushed during the last ``window_s`` seconds (t - window_s, t]."""

    def __init__(self, window_s: float) -> None:
        if not window_s > 0:
            raise ValueError(f"window_s must be positive, got {window_s}")
        self.window_s = window_s
        self._items: deque[tuple[float, float]] = deque()
        self.first_t: float | None = None

    def push(self, t: float, value: float) -> float:
        """Add ``value`` at time ``t`` (non-decreasing) and return the window's minimum."""
        items = self._items
        if items and t < items[-1][0]:
            raise ValueError(f"time went backwards: {t} after {items[-1][0]}")
        if self.first_t is None:
            self.first_t = t
        while items and items[-1][1] >= value:
            items.pop()
        items.append((t, value))
        horizon = t - self.window_s
        while items[0][0] <= horizon:
            items.popleft()
        return items[0][1]

    @property
    def minimum(self) -> float:
        return self._items[0][1] if self._items else 0.0

    def __len__(self) -> int:
        return len(self._items)
