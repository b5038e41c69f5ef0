"""Whether the board's sensors are really reporting: the part of flight health a link that is up does not tell.

A board can answer every request with a link that looks perfect while its
rangefinder reports nothing (every reading out of range), or with no optical
flow sensor at all. The controller then flies its failsafes (a gentle descent
without a range, the model's speed at reduced command speed without a flow), and
health must say so rather than ``ok`` (the session-32 review: a dead rangefinder
read ``ok`` with the controller in ``altitude_failsafe`` on 519 of 519 ticks).
Pure: fed each sensor's age and how long the link has been up.
"""

from __future__ import annotations

import math

from feelium.flight.config import FlightConfig

# A sensor is reported missing only after the link has been up this long (its first readings come within a tick)...
FIRST_READINGS_S = 1.0
# ...and the flow only once it has been silent this long: it drops out below its minimum height and on a plain floor,
# and health must not flap on each short gap (the speed estimate itself goes model-only after ``FLOW_FRESH_S``).
FLOW_MISSING_S = 1.0


def sensor_problems(ages_s: dict[str, float | None], up_for_s: float, config: FlightConfig) -> list[str]:
    """What the sensors' ages say is wrong, in words (none: every sensor reports). ``ages_s``: the newest reading's age
    per sensor (``range``, ``heading``, ``flow``; ``None``: none since the controller started); ``up_for_s``: how long
    the link has been up."""
    if up_for_s < FIRST_READINGS_S:
        return []
    limits = (("range", config.range_hold_s, "no rangefinder reading{}: altitude failsafe, sinking gently"),
              ("heading", config.telemetry_stale_s, "no heading{}: the heading is not held"),
              ("flow", FLOW_MISSING_S, "no measured speed{} (optical flow missing, without lock or too low): "
                                       "forward and backward at reduced speed"))
    problems = []
    for sensor, limit, words in limits:
        age = ages_s.get(sensor)
        if age is None or not math.isfinite(age):
            problems.append(words.format(" since the link came up"))
        elif age > limit:
            problems.append(words.format(f" for {age:.1f} s"))
    return problems
