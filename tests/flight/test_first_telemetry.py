"""Until the flight loop has fresh telemetry the motors are commanded neutral, however the daemon started.

The daemon starts the flight loop first (tests/daemon/test_startup_order.py); its first polls may find no board
yet, or replies made long before (a board that answered a previous process, a loop held up at start): neither
is acted on (issue 13, point 3: never on telemetry older than ``telemetry_max_age_s``).
"""

from __future__ import annotations

from dataclasses import replace

from feelium.daemon.config import Config
from feelium.flight.controller import FlightController
from feelium.flight.mixer import NEUTRAL, to_microseconds
from feelium.flight.setpoint import HOLD, setpoint_for_motion
from feelium.flight.telemetry import Telemetry

CONFIG = Config().flight
PERIOD = 1.0 / CONFIG.rate_hz


def _seen(t: float, age_s: float = 0.0) -> Telemetry:
    """A full poll made ``age_s`` before ``t``: the blimp at 1.5 m, heading 10 deg, still."""
    return Telemetry(t=t - age_s, range_m=1.5, heading_deg=10.0, yaw_rate_dps=0.0, battery_v=8.0)


def test_the_motors_are_neutral_until_fresh_telemetry_and_flown_from_then() -> None:
    controller = FlightController(CONFIG)
    forward = setpoint_for_motion("forward", CONFIG)  # a wearer already pressing: still nothing moves
    t = 100.0
    for _ in range(5):  # no board answering yet
        out = controller.step(t, None, forward)
        assert out.mode == "waiting" and out.motors_us == to_microseconds(NEUTRAL)
        t += PERIOD
    for _ in range(5):  # replies, but older than the controller may act on
        out = controller.step(t, _seen(t, age_s=CONFIG.telemetry_max_age_s + PERIOD), forward)
        assert out.mode == "waiting" and out.motors_us == to_microseconds(NEUTRAL)
        t += PERIOD
    assert controller.old_telemetry == 5
    out = controller.step(t, _seen(t), HOLD)
    assert out.mode == "flying" and out.altitude_m is not None


def test_telemetry_just_inside_the_age_limit_is_flown_on() -> None:
    """The other side of the limit, so the test above cannot pass by never flying at all."""
    controller = FlightController(replace(CONFIG, telemetry_max_age_s=0.1))
    out = controller.step(100.0, _seen(100.0, age_s=0.09), HOLD)
    assert out.mode == "flying" and controller.old_telemetry == 0
