"""Whether the body is inside its altitude limits: the part of flight health no sensor's age tells.

After a board stall or a dropped link the positively buoyant body floats to the room's ceiling, and on some plants it
goes back over the ceiling limit once it has come down, with the link up and every sensor fresh (issue 13;
docs/flight-robustness.md, session 35). Health said ``ok`` all along. A headset wearer, and anyone reading the log,
must be told when the blimp is where its limits say it may not be. Fed the altitude estimate and the time; no I/O.
"""

from __future__ import annotations

import math

from feelium.flight.config import FlightConfig
from feelium.flight.sensor_health import CLEAR_AFTER_S

# Reported past the limits by more than the safety goal allows (issue 13: "never outside by more than 10 cm")...
OUTSIDE_REPORTED_M = 0.1


class AltitudeWatch:
    """Judges the altitude estimate against ``altitude_min_m`` and ``altitude_max_m``, with hysteresis: once reported,
    the excursion stays reported until the body has been within the goal's tolerance for ``CLEAR_AFTER_S`` (a body
    bobbing across the line must not flip health, and log a line, on every crossing)."""

    def __init__(self, config: FlightConfig) -> None:
        self.low, self.high = config.altitude_min_m, config.altitude_max_m
        self._last_outside: tuple[float, float, str] | None = None  # when, by how much, which limit

    def problems(self, now: float, z: float | None, held: bool = False) -> list[str]:
        """What the altitude ``z`` (m; ``None``: no estimate, which the rangefinder's own report covers) says is wrong
        at ``now``, in words (none: inside the limits, or back inside long enough). ``held``: a partner's hand is on
        the body (the controller has softened): where it is then is the partner's doing, not a fault."""
        if z is not None and math.isfinite(z) and not held:
            high = z - self.high > self.low - z  # the nearer side is the one it may be past
            outside = z - self.high if high else self.low - z
            if outside > OUTSIDE_REPORTED_M:
                limit = "over the ceiling limit" if high else "under the floor limit"
                self._last_outside = (now, outside, limit)
                return [f"altitude {z:.2f} m: {outside:.2f} m {limit} ({self.high if high else self.low:.2f} m)"]
        if self._last_outside is None:
            return []
        when, by, limit = self._last_outside
        if now - when >= CLEAR_AFTER_S:
            self._last_outside = None
            return []
        return [f"altitude was {by:.2f} m {limit} {now - when:.1f} s ago"]
