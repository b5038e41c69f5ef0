"""Step a flight controller on the readings of a body held still, or on none: the tests that need a controller's own
decisions at an altitude, without a simulated plant."""

from __future__ import annotations

from feelium.flight.controller import FlightController
from feelium.flight.setpoint import HOLD
from feelium.flight.telemetry import Telemetry


def fly(controller: FlightController, t0: float, t1: float, range_m: float | None) -> None:
    """Step ``controller`` at its rate from ``t0`` to ``t1`` on fresh readings of ``range_m`` (heading 0, no yaw rate;
    ``None``: no replies at all, a stall)."""
    dt = 1.0 / controller.c.rate_hz
    for k in range(round((t1 - t0) / dt)):
        t = t0 + k * dt
        telemetry = None if range_m is None else Telemetry(t=t, range_m=range_m, heading_deg=0.0, yaw_rate_dps=0.0)
        controller.step(t, telemetry, HOLD)
