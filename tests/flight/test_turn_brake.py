"""A turn's brake on a plant whose motors lag twice as long as the config says (issue 13, point 1; session 22).

The brake used to follow a linear ramp tracked over the config's 80 ms lag: on corner-mTdL (light, strong, weak
drag, 150 ms lag) it ended with the reverse torque of the longer lag still in the pipe, the rate went on to +4 deg/s
the other way and decayed just under the stop goal's 3 deg/s for half a second: left-turn lapses 0.88-1.50 s at
flight seeds 1-6 (goal 1.5 s). Its reference now lands on zero through the box's longest lag (docs/flight-robustness.md,
session 22). Each flight is 2-3 s of CPU.
"""

from __future__ import annotations

import numpy as np
import pytest

from feelium.daemon.config import Config
from feelium.flight.loops import STOPPED_YAW_DPS
from feelium.lab.flight import safety
from feelium.lab.flight.plants import corner_plants
from feelium.lab.flight.simulation import SimFlight

CORNER = {plant.name: plant for plant in corner_plants()}["corner-mTdL"]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [2, 3])
def test_a_long_lag_turn_brake_does_not_overshoot_the_other_way(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The rate stays under the stop goal's threshold the other way: within 1 s of the release it reached +4.07 / +3.90
    deg/s (seeds 2 / 3) before, lapses 1.50 / 1.42 s; now 2.50 / 2.02 deg/s (a draft's, after the brake), 0.90 / 0.94 s."""
    flights: list[SimFlight] = []

    def recorded(*args: object, **kwargs: object) -> SimFlight:
        flights.append(SimFlight(*args, **kwargs))  # type: ignore[arg-type]
        return flights[-1]

    monkeypatch.setattr(safety, "SimFlight", recorded)
    result = safety.safety_flight(Config().flight, CORNER, seed=seed)
    t, r = flights[0].log["t"], flights[0].log["r_dps"]
    turning = np.nonzero(r < -10.0)[0]  # the left turn, the flight's last
    released = t[turning[-1]]
    after = (t > released) & (t < released + 1.0)
    assert np.max(r[after]) < STOPPED_YAW_DPS, f"overshoot {np.max(r[after]):.2f} deg/s"
    assert result.manoeuvres["turn_left-lapse"]["stop_s"] <= 1.2, result.manoeuvres


def test_a_repeated_timestamp_in_a_turns_brake_is_a_cycle_of_no_time_not_a_crash() -> None:
    """Two ticks at the same time (dt = 0: a clock step, a re-sent poll) while the turn brake runs: the brake's
    reference (``RateOnset`` with no handover taper) must not divide by the zero cycle (session 22 review)."""
    from feelium.flight.controller import FlightController
    from feelium.flight.setpoint import HOLD, Setpoint
    from feelium.flight.telemetry import Telemetry

    controller = FlightController(Config().flight)
    heading, rate, t = 0.0, 0.0, 0.0
    for k in range(120):  # 1.2 s of a right turn at 20 deg/s, then the release
        t = k * 0.01
        rate = min(20.0, rate + 0.5)
        heading = (heading + rate * 0.01) % 360.0
        setpoint = Setpoint(yaw_rate_dps=20.0) if k < 100 else HOLD
        out = controller.step(t, Telemetry(t, range_m=1.0, heading_deg=heading, yaw_rate_dps=rate), setpoint)
    assert controller.heading_loop.braking
    again = controller.step(t, Telemetry(t, range_m=1.0, heading_deg=heading, yaw_rate_dps=rate), HOLD)
    assert all(np.isfinite(again.commands)) and np.allclose(np.shape(again.commands), np.shape(out.commands))
