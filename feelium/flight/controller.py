"""The flight controller: a pure class, ``step(t, telemetry, setpoint) -> ControlOutput``.

Three loops share one mixer:

- altitude: rangefinder through an alpha-beta filter, PD on a smooth
  reference plus an integral that only runs near the target and never
  against a saturated output (anti-windup), with the net buoyancy as
  feed-forward (the vertical motors always push down about 0.36 N);
- heading: PD on the IMU heading with gyro yaw-rate damping;
- surge: a model-based speed observer (there is no airspeed sensor) so that
  releasing ``forward`` brakes actively instead of coasting.

A rate command (forward, up, turn...) starts at the largest acceleration
the actuators allow, through an onset reference that models the motor lag
(``_RateOnset``), so the body moves as soon as physics permits; releasing it
first brakes (damping only) and then holds the altitude or heading where the
body came to rest, so nothing springs back.
Failsafes (``docs/flight.md``) are decided here from telemetry age; time is
an input, so all of it runs faster than real time in tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from feelium.flight.config import FlightConfig
from feelium.flight.mixer import NEUTRAL, Mixer, MixerGeometry, thrust_for_command, to_microseconds
from feelium.flight.setpoint import Setpoint
from feelium.flight.telemetry import Telemetry

YAW_RATE_TAU_S = 0.06
SETTLE_S = 0.6  # damping-only phase after a braking ramp
RECOVERY_SETTLE_S = 2.5  # damping-only phase after telemetry returns from an outage
SETTLE_DAMPING = 6.0  # its damping, (m/s^2) per m/s and (rad/s^2) per rad/s
THRUST_LAG_S = 0.08
# Age of a rangefinder reading when the controller gets it: a VL53L1X-class sensor ranging at 50 Hz
# reports the middle of its 20 ms window, plus the transfer (the simulated board: 15 ms).
RANGE_LATENCY_S = 0.015
HANDOVER_S = 0.15  # time constant of the last part of a rate onset, where full thrust hands over to the rate loop
RESIDUAL_GATE_M = 0.06  # about 4 sigma of the rangefinder's noise at 2 m
RESIDUAL_GATE_S = 0.5  # a large innovation lasting longer than this is real and is learned


@dataclass(frozen=True)
class ControlOutput:
    """Motor commands and what the controller believes, for health and the state board."""

    t: float
    commands: tuple[float, float, float, float]
    motors_us: tuple[int, ...]
    mode: str  # flying | soft | range_hold | altitude_failsafe | telemetry_failsafe | waiting
    altitude_m: float | None
    altitude_target_m: float | None
    climb_m_s: float
    heading_deg: float | None
    heading_target_deg: float | None
    speed_m_s: float
    battery: str  # ok | low | critical | unknown
    battery_v: float | None


def wrap_deg(angle: float) -> float:
    """An angle difference folded into [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


class _Reference:
    """A critically damped second-order reference: targets are approached smoothly, never jumped to."""

    def __init__(self, omega: float) -> None:
        self.omega = omega
        self.value = 0.0
        self.rate = 0.0
        self.accel = 0.0

    def reset(self, value: float, rate: float = 0.0) -> None:
        self.value, self.rate, self.accel = value, rate, 0.0

    def advance(self, error: float, dt: float) -> None:
        """Move toward ``value + error`` (error given, so angles can wrap)."""
        w = self.omega
        self.accel = w * w * error - 2.0 * w * self.rate
        self.rate += self.accel * dt
        self.value += self.rate * dt


class _RateOnset:
    """The reference a rate command (forward, up, turn...) follows from its first cycle.

    A step in the reference rate asked for only gain x rate error at onset, well
    short of what the motors can give, so the body got going late. This
    reference instead models the body as the controller's feed-forward will
    move it: its acceleration follows the commanded one through the motor lag
    (``THRUST_LAG_S``). The command is the largest acceleration the actuators
    allow (``limits``: mixer limits, reverse thrust, drag) until the
    reference's *lag-aware predicted* rate (``rate + accel x lag``: where it
    ends up if the command went to zero now) comes within ``HANDOVER_S`` of
    the commanded rate, then tapers exponentially. The predicted rate moves
    exactly at the commanded acceleration, so it never passes the commanded
    rate, and the rate itself, which trails it by the lag, does not either;
    the damping compares the body's predicted rate with this one, the same
    instant, so when the body follows the model it adds nothing.
    """

    def __init__(self) -> None:
        self.rate = 0.0
        self.accel = 0.0  # after the motor lag

    def start(self, rate: float, accel: float) -> None:
        """Begin from the body's present rate and (modelled) acceleration, so nothing jumps."""
        self.rate, self.accel = rate, accel

    @property
    def predicted(self) -> float:
        return self.rate + self.accel * THRUST_LAG_S

    def step(self, target: float, limits: tuple[float, float], dt: float) -> tuple[float, float, float]:
        """This cycle's reference (rate, predicted rate, acceleration command); then advance over ``dt``."""
        rate, predicted = self.rate, self.predicted
        lo, hi = min(limits[0], 0.0), max(limits[1], 0.0)
        command = min(max((target - predicted) / max(HANDOVER_S, dt), lo), hi)
        decay = math.exp(-dt / THRUST_LAG_S)  # the command held over dt through the lag, exactly
        self.rate += command * dt + (self.accel - command) * THRUST_LAG_S * (1.0 - decay)
        self.accel = command + (self.accel - command) * decay
        return rate, predicted, command


class FlightController:
    """Altitude, heading and speed control with failsafes; no clock, no I/O."""

    def __init__(self, config: FlightConfig) -> None:
        self.c = config
        self.mixer = Mixer(
            MixerGeometry(
                arm_m=config.arm_m,
                horizontal_thrust_n=config.horizontal_thrust_n,
                vertical_thrust_n=config.vertical_thrust_n,
                horizontal_reverse_ratio=config.horizontal_reverse_ratio,
                vertical_reverse_ratio=config.vertical_reverse_ratio,
                deadband=config.motor_deadband,
                max_output=config.max_output,
                slew_per_s=config.slew_per_s,
            )
        )
        omega = 2.0 * math.pi * config.reference_hz
        self._last_t: float | None = None
        # altitude
        self.z_hat: float | None = None
        self.vz_hat = 0.0
        self._last_range_t: float | None = None
        self.z_target: float | None = None
        self._z_ref = _Reference(omega)
        self._climbing = False
        self._climb_onset = _RateOnset()
        self._braking_z = False
        self._settle_z_until: float | None = None
        self.disturbance = 0.0  # observed unmodelled vertical acceleration: the altitude loop's integral
        self._freeze_disturbance = False
        self._gated_since: float | None = None
        self._vertical_thrust = -config.net_buoyancy_n  # modelled upward motor force after the motor lag
        self._vertical_mean = self._vertical_thrust  # its mean over the last period
        self._up_n = -config.net_buoyancy_n
        self._altitude_failsafe = False
        # heading
        self.heading: float | None = None
        self.yaw_rate = 0.0
        self._last_heading_t: float | None = None
        self.heading_target: float | None = None
        self._psi_ref = _Reference(omega)
        self._turning = False
        self._turn_onset = _RateOnset()
        self._braking_yaw = False
        self._settle_yaw_until: float | None = None
        # surge
        self.speed_hat = 0.0
        self._speed_ref = 0.0
        self._surging = False
        self._surge_onset = _RateOnset()
        self._surge_thrust = 0.0
        self._surge_mean = 0.0
        self._yaw_torque = 0.0  # modelled yaw torque of the horizontal pair after the motor lag
        # What the last motor commands make once the lag has passed: vertical N (up), surge N, yaw N m.
        self._thrust_targets: tuple[float, float, float] | None = None
        # other
        self._was_soft = False
        self._telemetry_failsafe = False
        self.battery_v: float | None = None
        self.mode_counts: dict[str, int] = {}

    # ---------------------------------------------------------------- public
    def step(self, t: float, telemetry: Telemetry | None, setpoint: Setpoint) -> ControlOutput:
        """One control cycle at time ``t``: fold in the telemetry, return the motor commands."""
        dt = 1.0 / self.c.rate_hz if self._last_t is None else min(max(t - self._last_t, 0.0), 0.2)
        self._last_t = t
        self._advance_thrust_model(dt)
        if telemetry is not None:
            self._absorb(t, telemetry, dt)
        else:
            self._predict_only(dt)

        heading_age = math.inf if self._last_heading_t is None else t - self._last_heading_t
        range_age = math.inf if self._last_range_t is None else t - self._last_range_t
        if self.z_hat is None and self.heading is None:
            return self._output(t, self.mixer.limit(NEUTRAL, dt), "waiting", setpoint)

        stale = min(heading_age, range_age) > self.c.telemetry_stale_s
        if stale:
            self._telemetry_failsafe = True
            self._altitude_failsafe = True  # the next range reading restarts the altitude observer
            commands = self.mixer.mix(0.0, -self.c.failsafe_buoyancy_fraction * self.c.net_buoyancy_n, 0.0, dt)
            return self._output(t, commands, "telemetry_failsafe", setpoint)
        if self._telemetry_failsafe:
            # Back from a link outage, probably drifting up: damp the motion out, then hold
            # wherever the body comes to rest (no return trip through the air).
            self._telemetry_failsafe = False
            self._climbing = self._braking_z = self._turning = self._braking_yaw = False
            self._settle_z_until = self._settle_yaw_until = t + RECOVERY_SETTLE_S

        soft = setpoint.soften
        if self._was_soft and not soft:  # the partner let go: stay where they left it
            self.z_target, self.heading_target = self.z_hat, self.heading
            if self.z_hat is not None:
                self._z_ref.reset(self.z_hat)
            if self.heading is not None:
                self._psi_ref.reset(self.heading)
        self._was_soft = soft
        gain = self.c.soften_factor if soft else 1.0

        up_n, mode = self._altitude(t, dt, setpoint, range_age, gain, soft)
        yaw_nm = self._heading(t, dt, setpoint, heading_age, gain) if heading_age <= self.c.telemetry_stale_s else 0.0
        surge_n = self._surge(dt, 0.0 if soft else setpoint.forward_m_s, gain)
        commands = self.mixer.mix(surge_n, up_n, yaw_nm, dt)
        vertical = -sum(thrust_for_command(c, self.c.vertical_thrust_n, self.c.vertical_reverse_ratio, self.c.motor_deadband) for c in commands[2:])
        left, right = (thrust_for_command(c, self.c.horizontal_thrust_n, self.c.horizontal_reverse_ratio, self.c.motor_deadband) for c in commands[:2])
        self._thrust_targets = (vertical, left + right, (left - right) * self.c.arm_m)
        return self._output(t, commands, "soft" if soft and mode == "flying" else mode, setpoint)

    # ---------------------------------------------------------------- sensing
    def _advance_thrust_model(self, dt: float) -> None:
        """The modelled motor forces over the period just ended.

        The commands sent at its start held through it (the board applies them at once) and the
        motors followed them through their first-order lag: the *mean* force over the period
        drives the observers, the force at its end is the force now. Using the end value for
        the whole period led the body's real response by about half a period, which during a
        fast onset made the climb-rate estimate trail the real climb and the loop overshoot.
        After a failsafe cycle there is no target and the model holds (it is reset on recovery).
        """
        targets, self._thrust_targets = self._thrust_targets, None
        if targets is None or dt <= 0.0:
            self._vertical_mean, self._surge_mean = self._vertical_thrust, self._surge_thrust
            return
        decay = math.exp(-dt / THRUST_LAG_S)
        mean = 1.0 - THRUST_LAG_S / dt * (1.0 - decay)
        vertical, surge, yaw = targets
        self._vertical_mean = self._vertical_thrust + (vertical - self._vertical_thrust) * mean
        self._surge_mean = self._surge_thrust + (surge - self._surge_thrust) * mean
        self._vertical_thrust += (vertical - self._vertical_thrust) * (1.0 - decay)
        self._surge_thrust += (surge - self._surge_thrust) * (1.0 - decay)
        self._yaw_torque += (yaw - self._yaw_torque) * (1.0 - decay)

    def _absorb(self, t: float, tel: Telemetry, dt: float) -> None:
        if tel.battery_v is not None:
            self.battery_v = tel.battery_v
        if tel.range_m is not None:
            self._range_update(t, tel.range_m, dt)
        else:
            self._predict_altitude(dt)
        if tel.heading_deg is not None:
            if self.heading is None:
                self.heading_target = tel.heading_deg
                self._psi_ref.reset(tel.heading_deg)
            self.heading = tel.heading_deg
            self._last_heading_t = t
        if tel.yaw_rate_dps is not None:
            self.yaw_rate += (tel.yaw_rate_dps - self.yaw_rate) * min(1.0, dt / YAW_RATE_TAU_S)

    def _predict_only(self, dt: float) -> None:
        self._predict_altitude(dt)

    def _predict_altitude(self, dt: float) -> None:
        """Propagate the altitude observer with the modelled forces (thrust, buoyancy, drag)."""
        if self.z_hat is None:
            return
        c = self.c
        drag = c.quadratic_drag * self.vz_hat * abs(self.vz_hat) + 0.02 * self.vz_hat
        accel = (self._vertical_mean + c.net_buoyancy_n - drag) / c.mass_kg + self.disturbance
        self.z_hat += self.vz_hat * dt
        self.vz_hat += accel * dt

    def _range_update(self, t: float, range_m: float, dt: float) -> None:
        reacquired = self._last_range_t is None or self._altitude_failsafe
        self._last_range_t = t
        if self.z_hat is None or reacquired:
            self.z_hat, self.vz_hat = range_m, 0.0
            if self.z_target is None or self._altitude_failsafe:
                self.z_target = range_m
                self._z_ref.reset(range_m)
            if self._altitude_failsafe:  # it was floating up: damp that out, hold where it stops
                self._climbing = self._braking_z = False
                self._settle_z_until = t + RECOVERY_SETTLE_S
            self._altitude_failsafe = False
            return
        self._predict_altitude(dt)
        # The reading is RANGE_LATENCY_S old: compare it with where the body was then, or every
        # vertical acceleration (a climb's onset) leaves the climb-rate estimate trailing the body.
        residual = range_m - (self.z_hat - self.vz_hat * RANGE_LATENCY_S)
        # Observer poles: a double pole at p for altitude and speed, a slow one at q for the
        # disturbance, so the learned buoyancy error does not pick up rangefinder noise.
        p = 2.0 * math.pi * self.c.altitude_observer_hz
        q = 2.0 * math.pi * self.c.disturbance_observer_hz
        self.z_hat += (2.0 * p + q) * dt * residual
        self.vz_hat += (p * p + 2.0 * p * q) * dt * residual
        # A sudden large innovation is the body being moved or something passing under the
        # rangefinder, not a buoyancy error: do not learn from it, unless it persists.
        if abs(residual) <= RESIDUAL_GATE_M:
            self._gated_since = None
        elif self._gated_since is None:
            self._gated_since = t
        gated = self._gated_since is not None and t - self._gated_since < RESIDUAL_GATE_S
        if not self._freeze_disturbance and not gated:
            limit = self.c.altitude_integral_limit
            self.disturbance = min(max(self.disturbance + p * p * q * dt * residual, -limit), limit)

    # ---------------------------------------------------------------- loops
    def _altitude(self, t: float, dt: float, sp: Setpoint, range_age: float, gain: float, soft: bool) -> tuple[float, str]:
        c = self.c
        if range_age > c.range_hold_s or self.z_hat is None:
            self._altitude_failsafe = True
            self._up_n = -c.failsafe_buoyancy_fraction * c.net_buoyancy_n
            return self._up_n, "altitude_failsafe"
        if range_age > 0.0:
            return self._up_n, "range_hold"
        z = self.z_hat
        assert self.z_target is not None
        ref = self._z_ref
        climb = 0.0 if soft else sp.climb_m_s
        if climb:
            onset = self._climb_onset
            if not self._climbing:
                onset.start(self.vz_hat, self._climb_accel())
            self._climbing = True
            target = self._climb_within_limits(z, climb)
            ref.rate, rate_ahead, ref.accel = onset.step(target, self._climb_accel_limits(onset.rate), dt)
            ref.value = min(max(ref.value + ref.rate * dt, z - 0.25, c.altitude_min_m), z + 0.25, c.altitude_max_m)
            self.z_target = ref.value
        elif self._climbing:
            # Just released: decelerate along a planned ramp from the present climb rate, then hold
            # where that ramp ends, so the body neither coasts on nor springs back.
            self._climbing = False
            ref.reset(z, self.vz_hat)
            self._braking_z = True
        # While a rate is commanded only the rate is controlled: a position term would chase the
        # lag built up while spinning up and overshoot the commanded rate.
        p_gain = 0.0 if climb else 1.0
        if not climb and self._braking_z:
            ref.rate, ref.accel = _ramp_to_zero(ref.rate, c.brake_climb_m_s2, dt)
            ref.value += ref.rate * dt
            self.z_target = ref.value
            if ref.rate == 0.0:
                self._braking_z, self._settle_z_until = False, t + SETTLE_S
        elif not climb and self._settle_z_until is not None:
            # After the ramp the body may still drift a little (motor lag): damp it out and hold
            # where it comes to rest instead of pulling it back to the ramp's end.
            p_gain, gain = 0.0, gain * SETTLE_DAMPING / max(c.altitude_kd, 1e-6)
            ref.reset(z)
            self.z_target = z
            if t >= self._settle_z_until:
                self._settle_z_until = None
        elif not climb:
            if sp.altitude_m is not None:
                self.z_target = min(max(sp.altitude_m, c.altitude_min_m), c.altitude_max_m)
            ref.advance(self.z_target - ref.value, dt)
        error = min(max(ref.value - z, -c.altitude_error_limit_m), c.altitude_error_limit_m)
        # The damping compares rates at the moment a new command takes effect: the body's predicted
        # climb rate with, during a command, the onset reference's predicted rate (the same instant).
        rate_ref = rate_ahead if climb else ref.rate
        accel = gain * (p_gain * c.altitude_kp * error + c.altitude_kd * (rate_ref - self._predicted_climb())) + ref.accel - self.disturbance
        drag_ff = c.quadratic_drag * ref.rate * abs(ref.rate)
        up_n = c.mass_kg * accel - c.net_buoyancy_n + drag_ff
        lo, hi = self.mixer.limits_up_n()
        saturated = up_n >= hi or up_n <= lo
        # Anti-windup: the disturbance estimate (our integral) learns only while the loop is in
        # charge: not saturated, not softened by a touch, and near its target (a partner holding
        # the body away from it must not wind it up).
        far = max(abs(ref.value - z), abs(self.z_target - z)) > c.altitude_integral_band_m
        self._freeze_disturbance = soft or saturated or far
        self._up_n = min(max(up_n, lo), hi)
        return self._up_n, "flying"

    def _heading(self, t: float, dt: float, sp: Setpoint, heading_age: float, gain: float) -> float:
        c = self.c
        if self.heading is None or self.heading_target is None:
            return 0.0
        ref = self._psi_ref
        turn = 0.0 if sp.soften else sp.yaw_rate_dps
        if turn:
            onset = self._turn_onset
            if not self._turning:
                onset.start(math.degrees(self._yaw_rate_now()), math.degrees(self._yaw_accel()))
            self._turning = True
            ref.rate, rate_ahead, ref.accel = onset.step(turn, self._yaw_accel_limits_dps2(onset.rate), dt)
            ahead = wrap_deg(ref.value + ref.rate * dt - self.heading)
            ref.value = (self.heading + min(max(ahead, -20.0), 20.0)) % 360.0
            self.heading_target = ref.value
        elif self._turning:
            self._turning = False
            ref.reset(self.heading, self.yaw_rate)
            self._braking_yaw = True
        p_gain = 0.0 if turn else 1.0
        if not turn and self._braking_yaw:
            ref.rate, ref.accel = _ramp_to_zero(ref.rate, c.brake_yaw_dps2, dt)
            ref.value = (ref.value + ref.rate * dt) % 360.0
            self.heading_target = ref.value
            if ref.rate == 0.0:
                self._braking_yaw, self._settle_yaw_until = False, t + SETTLE_S
        elif not turn and self._settle_yaw_until is not None:
            p_gain, gain = 0.0, gain * SETTLE_DAMPING / max(c.heading_kd, 1e-6)
            ref.reset(self.heading)
            self.heading_target = self.heading
            if t >= self._settle_yaw_until:
                self._settle_yaw_until = None
        elif not turn:
            if sp.heading_deg is not None:
                self.heading_target = sp.heading_deg % 360.0
            ref.advance(wrap_deg(self.heading_target - ref.value), dt)
            ref.value %= 360.0
        error = math.radians(min(max(wrap_deg(ref.value - self.heading), -45.0), 45.0))
        rate_error = math.radians(rate_ahead if turn else ref.rate) - self._predicted_yaw_rate()
        alpha = gain * (p_gain * c.heading_kp * error + c.heading_kd * rate_error) + math.radians(ref.accel)
        r_ref = math.radians(ref.rate)
        return c.yaw_inertia_kg_m2 * alpha + c.yaw_drag * r_ref * abs(r_ref)

    def _climb_accel(self) -> float:
        """The vertical acceleration now, from the modelled forces."""
        c = self.c
        drag = c.quadratic_drag * self.vz_hat * abs(self.vz_hat) + 0.02 * self.vz_hat
        return (self._vertical_thrust + c.net_buoyancy_n - drag) / c.mass_kg + self.disturbance

    def _predicted_climb(self) -> float:
        """The climb rate when a new command takes effect (after the motor lag), from the modelled forces."""
        return self.vz_hat + self._climb_accel() * THRUST_LAG_S

    def _yaw_accel(self) -> float:
        """The yaw acceleration (rad/s^2) now, from the modelled torque and drag."""
        r = math.radians(self.yaw_rate)
        return (self._yaw_torque - self.c.yaw_drag * r * abs(r)) / self.c.yaw_inertia_kg_m2

    def _predicted_yaw_rate(self) -> float:
        """The yaw rate (rad/s) when a new command takes effect: the filtered gyro is about
        ``YAW_RATE_TAU_S`` old and the motors answer after ``THRUST_LAG_S``, so damping on the
        gyro alone brakes too late and overshoots; the modelled torque bridges both lags."""
        return math.radians(self.yaw_rate) + self._yaw_accel() * (YAW_RATE_TAU_S + THRUST_LAG_S)

    def _yaw_rate_now(self) -> float:
        """The yaw rate (rad/s) now: the filtered gyro brought forward over its filter lag."""
        return math.radians(self.yaw_rate) + self._yaw_accel() * YAW_RATE_TAU_S

    def _climb_within_limits(self, z: float, climb: float) -> float:
        """The commanded climb rate, slowed near ``altitude_min_m``/``altitude_max_m`` so that a held
        up or down stops there (at a quarter of the release deceleration, gentle enough for the
        onset reference and the motor lag to follow) instead of at the floor or the ceiling. The room
        left is counted from where the body will be once a slower command has taken effect."""
        c = self.c
        z_ahead = z + self.vz_hat * (HANDOVER_S + THRUST_LAG_S)
        room = c.altitude_max_m - z_ahead if climb > 0 else z_ahead - c.altitude_min_m
        allowed = math.sqrt(2.0 * 0.25 * c.brake_climb_m_s2 * max(room, 0.0))
        return math.copysign(min(abs(climb), allowed), climb)

    # The largest accelerations the actuators allow, each way, at a given rate: what a rate
    # command's onset asks for (the mixer's limits, reverse thrust, drag, buoyancy).
    def _climb_accel_limits(self, rate: float) -> tuple[float, float]:
        c = self.c
        lo, hi = self.mixer.limits_up_n()
        drag = c.quadratic_drag * rate * abs(rate) + 0.02 * rate
        return ((lo + c.net_buoyancy_n - drag) / c.mass_kg + self.disturbance,
                (hi + c.net_buoyancy_n - drag) / c.mass_kg + self.disturbance)

    def _yaw_accel_limits_dps2(self, rate_dps: float) -> tuple[float, float]:
        c = self.c
        r = math.radians(rate_dps)
        torque, drag = self.mixer.limit_yaw_nm(), c.yaw_drag * r * abs(r)
        return math.degrees((-torque - drag) / c.yaw_inertia_kg_m2), math.degrees((torque - drag) / c.yaw_inertia_kg_m2)

    def _surge_accel_limits(self, speed: float) -> tuple[float, float]:
        c = self.c
        lo, hi = self.mixer.limits_surge_n()
        drag = c.quadratic_drag * speed * abs(speed) + 0.02 * speed
        return (lo - drag) / c.mass_kg, (hi - drag) / c.mass_kg

    def _surge(self, dt: float, speed_sp: float, gain: float) -> float:
        c = self.c
        drag = c.quadratic_drag * self.speed_hat * abs(self.speed_hat) + 0.02 * self.speed_hat
        self.speed_hat += (self._surge_mean - drag) / c.mass_kg * dt
        if speed_sp:
            onset = self._surge_onset
            if not self._surging:
                onset.start(self.speed_hat, (self._surge_thrust - drag) / c.mass_kg)
            self._surging = True
            self._speed_ref, v_ahead, accel = onset.step(speed_sp, self._surge_accel_limits(onset.rate), dt)
        else:  # released: brake along a ramp the reverse thrust can follow
            self._surging = False
            self._speed_ref, accel = _ramp_to_zero(min(self._speed_ref, self.speed_hat, key=abs), c.brake_m_s2, dt)
        v = self._speed_ref
        feed_forward = c.mass_kg * accel + c.quadratic_drag * v * abs(v) + 0.02 * v
        # Damp the speed the body will have when a new command takes effect (motor lag), not
        # today's: otherwise braking carries on past zero and it creeps back the other way.
        predicted = self.speed_hat + (self._surge_thrust - drag) / c.mass_kg * THRUST_LAG_S
        return feed_forward + gain * c.mass_kg * c.speed_kp * ((v_ahead if speed_sp else v) - predicted)

    # ---------------------------------------------------------------- output
    def _battery(self) -> str:
        if self.battery_v is None:
            return "unknown"
        if self.battery_v <= self.c.battery_critical_v:
            return "critical"
        if self.battery_v <= self.c.battery_low_v:
            return "low"
        return "ok"

    def _output(self, t: float, commands: tuple[float, float, float, float], mode: str, sp: Setpoint) -> ControlOutput:
        self.mode_counts[mode] = self.mode_counts.get(mode, 0) + 1
        return ControlOutput(
            t=t,
            commands=commands,
            motors_us=to_microseconds(commands),
            mode=mode,
            altitude_m=self.z_hat,
            altitude_target_m=self.z_target,
            climb_m_s=self.vz_hat,
            heading_deg=self.heading,
            heading_target_deg=self.heading_target,
            speed_m_s=self.speed_hat,
            battery=self._battery(),
            battery_v=self.battery_v,
        )


def _ramp_to_zero(rate: float, decel: float, dt: float) -> tuple[float, float]:
    """One step of a constant-deceleration ramp from ``rate`` to zero: (new rate, acceleration)."""
    step = decel * dt
    if abs(rate) <= step:
        return 0.0, -rate / dt if dt > 0 else 0.0
    return rate - math.copysign(step, rate), -math.copysign(decel, rate)
