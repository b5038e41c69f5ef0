"""The one clock of the headset API, and how a client maps it to its own.

Every time the API exposes (``t`` of events and ``/state``, the capture time
of video frames and speech) is the daemon's monotonic clock in seconds
(``hub.clock``, ``time.monotonic``: it never jumps when NTP sets the wall
clock, which a Pi without a real-time clock does minutes after boot). A
headset measures frame age or touch-to-display latency by asking
``GET /clock`` for a pair of readings: the daemon clock and the wall clock
taken together, so ``wall_of(t) = t + offset_s``. Reading the daemon clock
on both sides of the wall clock bounds how far apart the two reads were.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

CAPTURE_HEADER = "X-Feelium-Capture-T"  # when a video frame or speech was captured, daemon clock, s


@dataclass(frozen=True)
class ClockReading:
    """The daemon clock and the wall clock at (nearly) the same moment."""

    t: float  # daemon clock, s
    wall: float  # Unix time, s
    uncertainty_s: float  # half the time between the two daemon-clock reads around the wall read

    @property
    def offset_s(self) -> float:
        """Add to a daemon-clock time to get Unix time (as good as the blimp's wall clock)."""
        return self.wall - self.t

    def wall_of(self, t: float) -> float:
        """The Unix time of daemon-clock time ``t``."""
        return t + self.offset_s

    def to_json(self) -> dict[str, float]:
        return {
            "t": round(self.t, 6),
            "wall": round(self.wall, 6),
            "offset_s": round(self.offset_s, 6),
            "uncertainty_s": round(self.uncertainty_s, 6),
        }


def read_clocks(daemon: Callable[[], float], wall: Callable[[], float]) -> ClockReading:
    """Read ``wall`` between two reads of ``daemon``; the daemon time is their midpoint."""
    before = daemon()
    now = wall()
    after = daemon()
    return ClockReading((before + after) / 2.0, now, max(0.0, after - before) / 2.0)
