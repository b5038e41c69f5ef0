"""How late the flight tick runs: a fixed-bin histogram of milliseconds, cheap enough for every 50 Hz tick.

Flight comes first, so the question "can the event loop's load delay the
control tick?" needs a figure over a whole run, not the newest sample: each
tick adds one count to a bin, and any two snapshots give the distribution in
between (``feelium bench board`` takes one at each end of its window). A
percentile is reported as the upper edge of the bin it falls in: an upper
bound, never flattering.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence

# Upper bin edges in ms; the last bin holds everything above the last edge.
EDGES_MS: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0, 50.0, 100.0, 200.0)


class LatenessHistogram:
    """Counts of lateness per bin (``EDGES_MS``); an early tick counts as on time."""

    def __init__(self, edges_ms: Sequence[float] = EDGES_MS) -> None:
        self.edges_ms = tuple(edges_ms)
        self.counts = [0] * (len(self.edges_ms) + 1)

    def record(self, late_s: float) -> None:
        self.counts[bisect.bisect_left(self.edges_ms, 1000.0 * late_s)] += 1

    def snapshot(self) -> dict[str, list[float] | list[int]]:
        return {"edges_ms": list(self.edges_ms), "counts": list(self.counts)}


def percentile_ms(edges_ms: Sequence[float], counts: Sequence[int], q: float) -> float | None:
    """The upper edge of the bin holding the ``q``-th percentile (``inf`` above the last edge); ``None`` if empty."""
    total = sum(counts)
    if total == 0:
        return None
    rank = math.ceil(total * q / 100.0)
    seen = 0
    for i, count in enumerate(counts):
        seen += count
        if seen >= max(rank, 1):
            return edges_ms[i] if i < len(edges_ms) else math.inf
    return math.inf  # pragma: no cover - the loop always reaches the total


def counts_between(first: Sequence[int], last: Sequence[int]) -> list[int]:
    """The counts recorded between two snapshots of one histogram."""
    return [b - a for a, b in zip(first, last, strict=True)]
