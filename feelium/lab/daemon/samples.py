"""A fixed block of float samples for a long measurement, so the measurement does not grow the process it measures.

A soak judges the daemon's resident memory growth. Its own lag probe samples
the loop 100 times a second; kept in a Python list, each sample is a float
object plus a pointer (~32 bytes), 3.5 MB over the 18 minutes between the two
medians the growth compares: most of the 5 MB budget, charged to the daemon.
This block is allocated and written once, before the window starts, so its
pages are resident from the first sample on and the figure is the daemon's.
"""

from __future__ import annotations

import numpy as np


class SampleBlock:
    """Up to ``capacity`` float samples in one preallocated, pre-touched array; beyond that they are counted, not kept."""

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be at least 1, got {capacity}")
        self._values = np.full(capacity, np.nan, dtype=np.float64)  # written now: every page resident before the run
        self._count = 0
        self.dropped = 0

    def add(self, value: float) -> None:
        if self._count < self._values.size:
            self._values[self._count] = value
            self._count += 1
        else:
            self.dropped += 1

    def clear(self) -> None:
        self._count = 0
        self.dropped = 0

    def values(self) -> np.ndarray:
        """The samples kept, oldest first (a copy: the block may be reused)."""
        return self._values[: self._count].copy()

    def __len__(self) -> int:
        return self._count
