"""What the controller believes about the body: modelled thrust, altitude, heading and yaw rate, speed.

Each estimator folds one kind of telemetry into a state the loops read; none
commands anything. The model (config mass, drag, thrust) only *predicts*
between measurements; every rate a loop damps is *measured*: the climb rate
through the rangefinder, the yaw rate by the gyro, the forward speed by the
downward optical-flow sensor. Where a measurement is missing the model
carries on alone and says so (``SurgeEstimate.measured``), and the loops
slow down (``docs/flight-robustness.md``).
"""

from __future__ import annotations

import math

from feelium.flight.config import FlightConfig
from feelium.flight.effectiveness import Effectiveness
from feelium.flight.references import THRUST_LAG_S

YAW_RATE_TAU_S = 0.06
# Age of a rangefinder reading when the controller gets it: a VL53L1X-class sensor ranging at 50 Hz
# reports the middle of its 20 ms window, plus the transfer.
RANGE_LATENCY_S = 0.015
RESIDUAL_GATE_M = 0.06  # about 4 sigma of the rangefinder's noise at 2 m
RESIDUAL_GATE_S = 0.5  # a large innovation lasting longer than this is real and is learned
# How fast the speed estimate follows the flow sensor (its noise is about 2 cm/s a sample): 3 s when the
# model is trusted (a fitted config: the flow only corrects drift), 80 ms when it may be off by 2x (the
# default: the flow is the speed), in between on a log scale (the exponent joins those two points).
FLOW_TAU_TRUSTED_S = 3.0
FLOW_TAU_EXPONENT = 5.23
FLOW_FRESH_S = 0.3  # older than this, the speed is the model's alone
MIN_FLOW_HEIGHT_M = 0.08


def air_drag(speed: float, quadratic: float) -> float:
    """The config's air drag (N) at ``speed``: quadratic, plus the small linear term of the body."""
    return quadratic * speed * abs(speed) + 0.02 * speed


def effectiveness_bounds(uncertainty: float, reverse: bool) -> tuple[float, float]:
    """How far the real acceleration per modelled push may be from 1: mass and thrust each off by
    ``uncertainty`` (and the reverse ratio too, for reverse pushes)."""
    low = uncertainty ** (-3 if reverse else -2)
    return low, uncertainty**2


class ThrustModel:
    """The modelled motor forces after the motor lag: vertical (N, up), surge (N), yaw (N m).

    The commands sent at a period's start held through it and the motors followed them
    through their first-order lag: the *mean* force over the period drives the observers,
    the force at its end is the force now. After a failsafe cycle there is no target and
    the model holds.
    """

    def __init__(self, net_buoyancy_n: float) -> None:
        self.vertical = -net_buoyancy_n
        self.surge = 0.0
        self.yaw = 0.0
        self.vertical_mean = self.vertical
        self.surge_mean = 0.0
        self.yaw_mean = 0.0
        self.targets: tuple[float, float, float] | None = None

    def advance(self, dt: float) -> None:
        targets, self.targets = self.targets, None
        if targets is None or dt <= 0.0:
            self.vertical_mean, self.surge_mean, self.yaw_mean = self.vertical, self.surge, self.yaw
            return
        decay = math.exp(-dt / THRUST_LAG_S)
        mean = 1.0 - THRUST_LAG_S / dt * (1.0 - decay)
        vertical, surge, yaw = targets
        self.vertical_mean = self.vertical + (vertical - self.vertical) * mean
        self.surge_mean = self.surge + (surge - self.surge) * mean
        self.yaw_mean = self.yaw + (yaw - self.yaw) * mean
        self.vertical += (vertical - self.vertical) * (1.0 - decay)
        self.surge += (surge - self.surge) * (1.0 - decay)
        self.yaw += (yaw - self.yaw) * (1.0 - decay)


class AltitudeObserver:
    """Altitude and climb rate from the rangefinder and the modelled vertical force, with the unmodelled
    vertical acceleration (buoyancy error, thrust error) learned slowly as the altitude loop's integral."""

    def __init__(self, config: FlightConfig) -> None:
        self.c = config
        self.z: float | None = None
        self.vz = 0.0
        self.last_range_t: float | None = None
        self.disturbance = 0.0
        self.freeze_disturbance = False
        self.reacquire = False  # set by a failsafe: the next reading restarts the observer
        self._gated_since: float | None = None

    def accel(self, up_force_n: float) -> float:
        c = self.c
        return (up_force_n + c.net_buoyancy_n - air_drag(self.vz, c.quadratic_drag)) / c.heave_mass + self.disturbance

    def predict(self, up_force_n: float, dt: float) -> None:
        """Propagate with the modelled forces (thrust, buoyancy, drag)."""
        if self.z is None:
            return
        accel = self.accel(up_force_n)
        self.z += self.vz * dt
        self.vz += accel * dt

    def update(self, t: float, range_m: float, up_force_n: float, dt: float) -> bool:
        """Fold in one reading; ``True`` when it (re)started the observer rather than corrected it."""
        restarted = self.last_range_t is None or self.reacquire or self.z is None
        self.last_range_t = t
        if restarted:
            self.z, self.vz, self.reacquire = range_m, 0.0, False
            return True
        self.predict(up_force_n, dt)
        assert self.z is not None
        # The reading is RANGE_LATENCY_S old: compare it with where the body was then.
        residual = range_m - (self.z - self.vz * RANGE_LATENCY_S)
        p = 2.0 * math.pi * self.c.altitude_observer_hz
        q = 2.0 * math.pi * self.c.disturbance_observer_hz
        self.z += (2.0 * p + q) * dt * residual
        self.vz += (p * p + 2.0 * p * q) * dt * residual
        # A sudden large innovation is the body being moved or something passing under the
        # rangefinder, not a buoyancy error: do not learn from it, unless it persists.
        if abs(residual) <= RESIDUAL_GATE_M:
            self._gated_since = None
        elif self._gated_since is None:
            self._gated_since = t
        gated = self._gated_since is not None and t - self._gated_since < RESIDUAL_GATE_S
        if not self.freeze_disturbance and not gated:
            limit = self.c.altitude_integral_limit
            self.disturbance = min(max(self.disturbance + p * p * q * dt * residual, -limit), limit)
        return False


class YawEstimate:
    """Heading (the board's, gyro-integrated) and yaw rate (gyro, lightly filtered), plus how strongly
    the body answers a yaw torque."""

    def __init__(self, config: FlightConfig) -> None:
        self.c = config
        self.heading: float | None = None
        self.rate_dps = 0.0
        self.last_heading_t: float | None = None
        low, high = effectiveness_bounds(config.plant_uncertainty, reverse=False)
        self.effectiveness = Effectiveness(low * _yaw_reverse_share(config), high, min_change=0.01)

    def update(self, t: float, dt: float, heading_deg: float | None, gyro_dps: float | None, torque_mean: float) -> None:
        if heading_deg is not None:
            self.heading = heading_deg
            self.last_heading_t = t
        push = torque_mean / self.c.yaw_inertia_kg_m2
        if gyro_dps is not None:
            self.rate_dps += (gyro_dps - self.rate_dps) * min(1.0, dt / YAW_RATE_TAU_S)
        self.effectiveness.update(t, dt, push, None if gyro_dps is None else math.radians(gyro_dps))

    def accel(self, torque_nm: float) -> float:
        """The yaw acceleration (rad/s^2) the model and the learned effectiveness give for ``torque_nm`` now."""
        r = math.radians(self.rate_dps)
        push = torque_nm / self.c.yaw_inertia_kg_m2
        return self.effectiveness.value(push) * push - self.c.yaw_drag * r * abs(r) / self.c.yaw_inertia_kg_m2


def _yaw_reverse_share(config: FlightConfig) -> float:
    """A yaw torque is one motor forward, one reversed: the worst reverse ratio costs this share of it."""
    ratio = config.horizontal_reverse_ratio
    worst = ratio / config.plant_uncertainty
    return (1.0 + worst) / (1.0 + ratio) if ratio > 0 else 1.0


class SurgeEstimate:
    """Forward ground speed: the modelled surge force predicts, the optical-flow sensor corrects.

    Without the flow sensor (none fitted, no lock over a dark or featureless floor, out of
    its height range) the speed is the model's alone, which on an unknown blimp may be off
    by a factor of four; ``measured`` says which, and the surge loop slows down.
    """

    def __init__(self, config: FlightConfig) -> None:
        self.c = config
        self.speed = 0.0
        self.last_flow_t: float | None = None
        self.last_measured: float | None = None
        low, high = effectiveness_bounds(config.plant_uncertainty, reverse=False)
        reverse_low, _ = effectiveness_bounds(config.plant_uncertainty, reverse=True)
        self.effectiveness = Effectiveness(low, high, reverse_low=reverse_low, min_change=0.005)

    def measured(self, t: float) -> bool:
        return self.last_flow_t is not None and t - self.last_flow_t <= FLOW_FRESH_S

    def update(self, t: float, dt: float, surge_mean_n: float, flow_x_rad_s: float | None, height_m: float | None) -> None:
        c = self.c
        push = surge_mean_n / c.mass_kg
        self.speed += (self.effectiveness.value(push) * push - air_drag(self.speed, c.quadratic_drag) / c.mass_kg) * dt
        measured = None
        if flow_x_rad_s is not None and height_m is not None and height_m >= MIN_FLOW_HEIGHT_M:
            measured = flow_x_rad_s * height_m
            tau = FLOW_TAU_TRUSTED_S / c.plant_uncertainty**FLOW_TAU_EXPONENT
            self.speed += (measured - self.speed) * (1.0 - math.exp(-dt / tau))
            self.last_flow_t, self.last_measured = t, measured
        self.effectiveness.update(t, dt, push, measured)

    def accel(self, surge_n: float) -> float:
        """The forward acceleration the model and the learned effectiveness give for ``surge_n`` now."""
        push = surge_n / self.c.mass_kg
        return self.effectiveness.value(push) * push - air_drag(self.speed, self.c.quadratic_drag) / self.c.mass_kg
