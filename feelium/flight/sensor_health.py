"""Whether the board's sensors are really reporting: the part of flight health a link that is up does not tell.

A board can answer every request with a link that looks perfect while its
rangefinder reports nothing (every reading out of range), or with no optical
flow sensor at all. The controller then flies its failsafes (a slow rise
without a range, the model's speed at reduced command speed without a flow),
and health must say so rather than ``ok`` (the session-32 review: a dead
rangefinder read ``ok`` with the controller in ``altitude_failsafe`` on 519 of
519 ticks). Fed each sensor's age and how long the link has been up; no I/O.
"""

from __future__ import annotations

import math

from feelium.flight.config import FlightConfig
from feelium.flight.estimators import FLOW_NOISE_RAD_S

# A sensor is reported missing only after the link has been up this long (its first readings come within a tick)...
FIRST_READINGS_S = 1.0
# ...and the flow only once it has been silent this long: it drops out below its minimum height and on a plain floor,
# and each short gap must not be news (the speed estimate itself goes model-only after ``FLOW_FRESH_S``).
FLOW_MISSING_S = 1.0
# Once reported, a sensor stays reported until it has been fresh this long: a flow that loses lock 1.5 s of every
# 3.3 s flipped health ok/degraded 20 times a minute, each flip a log line (the session-32 review).
CLEAR_AFTER_S = 5.0
# A flow measured this many times noisier than the speed control was judged with is reported (and cleared again under
# NOISY_FLOW_CLEAR): at twice the noise 128 held commands through stalls and drops kept every goal, at three times
# the heavy corners' stops took up to 3.8 s (docs/flight-robustness.md, session 33).
NOISY_FLOW = 2.0
NOISY_FLOW_CLEAR = 1.8


class SensorWatch:
    """Judges the rangefinder, the heading and the optical flow from their ages, with hysteresis.

    Health is read at any moment, not on the control tick, so each limit has one control period and one reply
    timeout added: a reading on its way is not a silent sensor.
    """

    def __init__(self, config: FlightConfig) -> None:
        slack = 1.0 / config.rate_hz + config.reply_timeout_s
        self.limits = {"range": config.range_hold_s + slack, "heading": config.telemetry_stale_s + slack,
                       "flow": FLOW_MISSING_S + slack}
        self._reported: dict[str, float] = {}  # sensor -> when it was last seen silent past its limit
        self._noisy_flow = False

    def problems(self, now: float, ages_s: dict[str, float | None], up_for_s: float,
                 flow_noise_rad_s: float = FLOW_NOISE_RAD_S) -> list[str]:
        """What the sensors' ages say is wrong, in words (none: every sensor reports). ``ages_s``: the newest
        reading's age per sensor (``range``, ``heading``, ``flow``; ``None``: none since the controller started);
        ``up_for_s``: how long the link has been up; ``flow_noise_rad_s``: the flow's noise as measured in flight."""
        if up_for_s < FIRST_READINGS_S:
            return []
        out = []
        times = flow_noise_rad_s / FLOW_NOISE_RAD_S
        self._noisy_flow = times > (NOISY_FLOW_CLEAR if self._noisy_flow else NOISY_FLOW)
        if self._noisy_flow:
            out.append(f"optical flow noisy ({flow_noise_rad_s:.3f} rad/s, {times:.1f} times what the speed control was judged"
                       " with): stops may be slow")
        for sensor, words in WORDS.items():
            age = ages_s.get(sensor)
            silent = age is None or not math.isfinite(age) or age > self.limits[sensor]
            if silent:
                self._reported[sensor] = now
            elif now - self._reported.get(sensor, -math.inf) >= CLEAR_AFTER_S:
                self._reported.pop(sensor, None)
                continue
            if age is None or not math.isfinite(age):
                out.append(words.format("since the link came up"))
            elif silent:
                out.append(words.format(f"for {age:.1f} s"))
            else:
                out.append(words.format(f"{now - self._reported[sensor]:.1f} s ago, intermittent"))
        return out


WORDS = {
    "range": "no rangefinder reading {}: altitude failsafe, rising slowly (the motors cancel most of the buoyancy)",
    "heading": "no heading {}: the heading is not held",
    "flow": "no measured speed {} (optical flow missing, without lock or too low): forward and backward at reduced speed",
}
