"""An untuned textbook PID, the yardstick for the controller's quietness and accuracy.

Same sensors, same mixer geometry, none of the care: derivative taken from
raw rangefinder differences, no observer, no thrust-curve inversion, no
slew limit, no reference smoothing. It is what a first attempt looks like,
which is what ``feelium bench flight`` compares against.
"""

from __future__ import annotations


from feelium.flight.config import FlightConfig
from feelium.flight.controller import ControlOutput
from feelium.flight.references import wrap_deg
from feelium.flight.mixer import to_microseconds
from feelium.flight.setpoint import Setpoint
from feelium.flight.telemetry import Telemetry


class BaselinePid:
    """Altitude and heading PID straight to the motor commands."""

    KP, KI, KD = 2.0, 0.5, 1.0  # command per metre, per metre-second, per metre/second
    HEADING_KP, HEADING_KD = 0.02, 0.01  # command per degree, per degree/second

    def __init__(self, config: FlightConfig) -> None:
        self.c = config
        self.z_target: float | None = None
        self.heading_target: float | None = None
        self.integral = 0.0
        self._last_z: float | None = None
        self._last_t: float | None = None
        self._up = 0.5
        self._yaw = 0.0

    def step(self, t: float, telemetry: Telemetry | None, setpoint: Setpoint) -> ControlOutput:
        dt = 1.0 / self.c.rate_hz if self._last_t is None else max(t - self._last_t, 1e-3)
        self._last_t = t
        z = telemetry.range_m if telemetry else None
        if z is not None:
            if self.z_target is None:
                self.z_target = z
            if setpoint.altitude_m is not None:
                self.z_target = setpoint.altitude_m
            error = self.z_target - z
            derivative = 0.0 if self._last_z is None else -(z - self._last_z) / dt
            self._last_z = z
            self.integral += error * dt
            # Vertical motors push down: more down-thrust when too high.
            self._up = min(max(0.5 - (self.KP * error + self.KI * self.integral + self.KD * derivative), -1.0), 1.0)
        heading = telemetry.heading_deg if telemetry else None
        if heading is not None:
            if self.heading_target is None:
                self.heading_target = heading
            if setpoint.heading_deg is not None:
                self.heading_target = setpoint.heading_deg
            rate = telemetry.yaw_rate_dps or 0.0 if telemetry else 0.0
            self._yaw = self.HEADING_KP * wrap_deg(self.heading_target - heading) - self.HEADING_KD * rate
        yaw = min(max(self._yaw, -1.0), 1.0)
        commands = (yaw, -yaw, self._up, self._up)
        return ControlOutput(
            t=t,
            commands=commands,
            motors_us=to_microseconds(commands),
            mode="baseline",
            altitude_m=z,
            altitude_target_m=self.z_target,
            climb_m_s=0.0,
            heading_deg=heading,
            heading_target_deg=self.heading_target,
            speed_m_s=0.0,
            battery="unknown",
            battery_v=None,
        )


