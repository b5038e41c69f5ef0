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
from collections import deque

from feelium.flight.config import FlightConfig
from feelium.flight.effectiveness import Effectiveness

YAW_RATE_TAU_S = 0.06
# The heading between the board's whole degrees: the gyro carries it, the board's heading pulls it back
# over this long (its rounding, +-0.5 deg, averages out; a gyro bias cannot build up).
FINE_HEADING_TAU_S = 1.0
# Age of a rangefinder reading when the controller gets it: a VL53L1X-class sensor ranging at 50 Hz
# reports the middle of its 20 ms window, plus the transfer.
RANGE_LATENCY_S = 0.015
# The climb rate measured by the rangefinder alone (no model): the least-squares slope of the readings
# of this window. It teaches the heave effectiveness, so it must not lean on the model it checks.
RANGE_RATE_WINDOW_S = 0.3
RANGE_RATE_MIN_SAMPLES = 6
CLIMB_RATE_TAU_S = 0.1  # how fast the climb rate follows the range slope at plant_uncertainty 2 (never at 1)
DISTURBANCE_FROM_RATE_TAU_S = 3.0  # and how fast the disturbance learns what the model missed of it...
NEW_HOLD_S, NEW_HOLD_TAU_S = 5.0, 0.5  # ...and how fast in the first seconds of a hold, when nothing is learned yet
# ...but from the climb rate never faster than this, m/s^2 per s. A step is the rate's miss over the learned
# effectiveness, and a side's first windows may read that a quarter of its value: in a first hover the disturbance then
# leapt from -0.46 to +0.38 m/s^2 (true -0.25) in half a second and corner-MTdL fell to the floor (flight seed 52;
# docs/flight-robustness.md, session 30). What it learns (buoyancy, the model's hover force) changes slower; a first hold
# still finds it in about a second. (Limiting the position residual's slow integral too took two flights of 1152 past
# the altitude goal: session 30.)
DISTURBANCE_SLEW_M_S3 = 1.0
HEAVE_WINDOW_S = 0.5  # its effectiveness windows: longer than the surge's, the range slope is noisier
HEAVE_MIN_CHANGE = 0.03  # m/s of modelled climb-rate change: below it a window is noise, not excitation
# The noise of one heave window's measured climb-rate change: the difference of two range slopes, each over 15
# readings of a VL53L1X-class sensor (1.6 cm at 1.6 m): sqrt(2) x 0.048 = 0.068 m/s; with the drafts and the model's
# error, the windows of safety flights scatter 0.06-0.09 m/s about their least squares (session 22). What the
# altitude's limit margin counts on is the learned value two of its standard errors low (Effectiveness.change_noise).
HEAVE_CHANGE_NOISE_M_S = 0.08
# In a held climb on a trusted model (heave uncertainty 1), away from the altitude limits, the observer follows
# the rangefinder at this share of its bandwidth: the climb's rate loop damps the observer's climb rate and
# nothing else, and at 0.6 Hz the rangefinder's noise (1.6 cm) moved that rate 2.5-3 cm/s for half a second,
# the body with it (test_onset's held `up`, seed 3: 1.030 of the commanded climb). The model it leans on
# instead is the one the user trusts.
HELD_CLIMB_OBSERVER_SHARE = 0.5
RESIDUAL_GATE_M = 0.06  # about 4 sigma of the rangefinder's noise at 2 m
RESIDUAL_GATE_S = 0.5  # a large innovation lasting longer than this is real and is learned
# How fast the speed estimate follows the flow sensor (its noise is about 2 cm/s a sample): see flow_tau_s.
FLOW_TAU_TRUSTED_S = 3.0
FLOW_TAU_BOX_S = FLOW_TAU_TRUSTED_S / 2.0**5.23  # 80 ms at the shipped uncertainty, 2: exactly the value it had
# The speed that decides "still or moving" (the hover band) follows the flow at least this fast: see
# SurgeEstimate.decision_speed (measured on the 6 calibrated light corners: 0.08-0.2 s all stop within 0.5 s).
DECISION_FLOW_TAU_S = 0.15
YAW_CONFIRMING_CHANGE_RAD_S = 0.035  # 2 deg/s of measured yaw-rate change in a window: a turn or a brake, not a nudge
SURGE_ASSURING_CHANGE_M_S = 0.02  # a window must change the modelled speed this much to teach the stop's margin
SURGE_CONFIRMING_CHANGE_M_S = 0.08  # measured in a window: a command or a brake, not a drift nor the flow noise (0.034 m/s)
# The flow sensor's noise (PMW3901 class, as the simulator's), rad/s per reading: a window's measured speed change has
# root 2 times it, times the height. What the flight teaches the stop's margin counts once it is known to this standard
# error (``Effectiveness(assuring_error=...)``; a brake of the nominal blimp at 1.2 m pins it in about 0.1 s).
# The noise is also measured in flight (``SurgeEstimate.flow_noise_rad_s``), never counted below this: a real sensor
# over a real floor may be noisier than the simulator's, and a margin that counted on less noise than it has would
# take a noisy window for a brake again.
FLOW_NOISE_RAD_S = 0.02
FLOW_NOISE_TAU_S = 5.0  # the measured noise follows successive readings' differences within this
SURGE_ASSURING_ERROR = 2.0
FLOW_FRESH_S = 0.3  # older than this, the speed is the model's alone
# Without the flow the learned model bias fades over this: the model alone must not carry a draft long gone.
SURGE_BIAS_FORGET_S = 1.0
MIN_FLOW_HEIGHT_M = 0.08


def air_drag(speed: float, quadratic: float) -> float:
    """The config's air drag (N) at ``speed``: quadratic, plus the small linear term of the body."""
    return quadratic * speed * abs(speed) + 0.02 * speed


def flow_tau_s(uncertainty: float) -> float:
    """How long the speed estimate trusts the model over the flow sensor, for a surge model this uncertain.

    The model's speed drifts from the truth at a rate that grows with its error (an effectiveness off by up
    to U^2 - 1), so over a time constant tau the estimate is biased by about (U^2 - 1) tau, while the flow's
    noise it lets through falls as 1/sqrt(tau); their sum is least for tau proportional to (U^2 - 1)^(-2/3).
    Anchored at the shipped box's 80 ms (2: the flow is the speed; exactly the old value, so the shipped
    controller flies as it did: 0.07 % more moved a corner's hover reversals from 0.70 to 0.73 /s) and capped at 3 s for a model trusted
    outright (1: the flow only corrects drift). The curve before this one (3 s / U^5.23) joined the same two
    ends but still trusted a fitted model for 1.3-2.2 s at U 1.1-1.17: a surge model 10 % off then cruised
    10 % off, since the flow had no time to correct it within a held command.
    """
    if uncertainty <= 1.0:
        return FLOW_TAU_TRUSTED_S
    return min(FLOW_TAU_TRUSTED_S, FLOW_TAU_BOX_S * (3.0 / (uncertainty * uncertainty - 1.0)) ** (2.0 / 3.0))


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

    def __init__(self, net_buoyancy_n: float, lag_s: float) -> None:
        self.lag_s = lag_s
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
        decay = math.exp(-dt / self.lag_s)
        mean = 1.0 - self.lag_s / dt * (1.0 - decay)
        vertical, surge, yaw = targets
        self.vertical_mean = self.vertical + (vertical - self.vertical) * mean
        self.surge_mean = self.surge + (surge - self.surge) * mean
        self.yaw_mean = self.yaw + (yaw - self.yaw) * mean
        self.vertical += (vertical - self.vertical) * (1.0 - decay)
        self.surge += (surge - self.surge) * (1.0 - decay)
        self.yaw += (yaw - self.yaw) * (1.0 - decay)


class RangeRate:
    """The climb rate from the rangefinder alone: the least-squares slope of the readings of the last
    ``window_s``. It describes the middle of its window: it is ``age_s`` old when read."""

    def __init__(self, window_s: float = RANGE_RATE_WINDOW_S) -> None:
        self.window_s = window_s
        self._readings: deque[tuple[float, float]] = deque()
        self._added = 0  # readings added or cleared so far: with ``t``, what a slope depends on
        self._slope: tuple[float, int, float | None] | None = None  # (t, _added, slope) of the last rate()

    @property
    def age_s(self) -> float:
        return 0.5 * self.window_s + RANGE_LATENCY_S

    def add(self, t: float, range_m: float) -> None:
        self._readings.append((t, range_m))
        self._added += 1

    def clear(self) -> None:
        self._readings.clear()
        self._added += 1

    def rate(self, t: float) -> float | None:
        """The slope over the window ending at ``t``, or ``None`` with too few readings (dropouts, a restart).

        A control cycle asks twice (the climb-rate correction, then the effectiveness) with nothing added
        between: the second time it is the first answer, not a second pass over the window."""
        cached = self._slope
        if cached is not None and cached[0] == t and cached[1] == self._added:
            return cached[2]
        slope = self._fit(t)
        self._slope = (t, self._added, slope)
        return slope

    def _fit(self, t: float) -> float | None:
        readings = self._readings
        while readings and readings[0][0] < t - self.window_s + 1e-9:
            readings.popleft()
        n = len(readings)
        if n < RANGE_RATE_MIN_SAMPLES:
            return None
        times, ranges = zip(*readings)
        t_mean = sum(times) / n
        z_mean = sum(ranges) / n
        spread = sum((x - t_mean) ** 2 for x in times)
        return sum((x - t_mean) * (z - z_mean) for x, z in zip(times, ranges)) / spread if spread > 0.0 else None


class AltitudeObserver:
    """Altitude and climb rate from the rangefinder and the modelled vertical force, with the unmodelled
    vertical acceleration (buoyancy error, thrust error) learned slowly as the altitude loop's integral.

    How strongly the body answers a change of the modelled net force (the heave effectiveness: mass
    and thrust may each be off by its axis' uncertainty) is learned against the rangefinder's own
    slope (:class:`RangeRate`), never against this observer's climb rate, which leans on the model.
    The modelled push is delayed to the slope's age, so both describe the same moment.
    """

    def __init__(self, config: FlightConfig) -> None:
        self.c = config
        self.z: float | None = None
        self.vz = 0.0
        self.last_range_t: float | None = None
        self.disturbance = 0.0
        self.freeze_disturbance = False
        # set by the loop: a partner's hand is on the body, or it is far below its target (the loop's anti-windup);
        # either way the model misses a force: its motion teaches nothing and the climb rate is the range slope
        self.touched = False
        self.climbing = False  # set by the loop: a climb (or descent) command is held, away from the limits
        self.reacquire = False  # set by a failsafe: the next reading restarts the observer
        self._gated_since: float | None = None
        self._restart_t = -math.inf
        low, high = effectiveness_bounds(config.uncertainty("heave"), reverse=False)
        self.effectiveness = Effectiveness(low, high, window_s=HEAVE_WINDOW_S, min_change=HEAVE_MIN_CHANGE, steady_bias=True,
                                           change_noise=HEAVE_CHANGE_NOISE_M_S)
        self.range_rate = RangeRate()
        self._pushes: deque[tuple[float, float]] = deque(maxlen=max(1, round(self.range_rate.age_s * config.rate_hz)) + 1)

    def push(self, up_force_n: float) -> float:
        """The modelled net vertical acceleration of ``up_force_n``: thrust, buoyancy and drag over the mass."""
        c = self.c
        return (up_force_n + c.net_buoyancy_n - air_drag(self.vz, c.quadratic_drag)) / c.heave_mass

    def accel(self, up_force_n: float) -> float:
        """The body's acceleration: the learned effectiveness times the push beyond the hover push.

        The disturbance is the push that holds the body still (the negative of the hover push), so
        the effectiveness scales only what the loop changes: a wrong effectiveness never moves the
        hover force, and learning it never disturbs the hold."""
        push = self.push(up_force_n) + self.disturbance
        return self.effectiveness.value(push) * push

    def _correct_climb_rate(self, t: float, dt: float, up_force_n: float) -> None:
        """Pull the climb rate toward the rangefinder's own slope, as strongly as the model is doubted.

        Between readings the climb rate is the model's; on a blimp whose thrust or mass is off by 2x
        (and before the disturbance is learned) that rate may be off by half a metre per second while
        the altitude still looks close, and the loop would not damp a fall it cannot see. The slope
        is compared with the estimate brought back to the slope's age; while ``touched`` it is taken as it is."""
        gain = (self.c.uncertainty("heave") - 1.0) / CLIMB_RATE_TAU_S
        slope = self.range_rate.rate(t) if gain > 0.0 or self.touched else None
        if slope is None:
            return
        if self.touched:
            # Held or far below the target the disturbance is frozen (the loop's anti-windup; only a new hold still
            # learns it), so the model's error stays in its acceleration: the climb rate is the slope, not brought
            # forward by that acceleration over the slope's age. On the floor the model's push, which the floor met,
            # held the climb rate at the push times that age, +0.18 m/s, with the rangefinder at 1 cm; the loop,
            # seeing a climb, never pushed harder, and three random plants sank in their first hover and stayed
            # (docs/flight-robustness.md, session 27).
            missed = slope - self.vz
        else:
            then = self.vz - self.accel(up_force_n) * self.range_rate.age_s
            missed = min(1.0, gain * dt) * (slope - then)  # the climb rate the model did not predict
        self.vz += missed
        if self._may_learn(t):  # and the acceleration it missed is the disturbance's to learn
            limit = self.c.altitude_integral_limit
            tau = DISTURBANCE_FROM_RATE_TAU_S if t - self._restart_t > NEW_HOLD_S else NEW_HOLD_TAU_S
            step = missed / (tau * self.effectiveness.value(self.push(up_force_n) + self.disturbance))
            slew = DISTURBANCE_SLEW_M_S3 * dt
            self.disturbance = min(max(self.disturbance + min(max(step, -slew), slew), -limit), limit)

    def _may_learn(self, t: float) -> bool:
        """The disturbance learns while the loop is in charge (not held, not saturated: a hand must not
        wind it up into a lunge when it lets go) or the hold is new (nothing learned yet), and never from
        a sudden large innovation (the body moved by a hand, something passing under the rangefinder)
        unless that persists."""
        gated = self._gated_since is not None and t - self._gated_since < RESIDUAL_GATE_S
        return not gated and (not self.freeze_disturbance or t - self._restart_t <= NEW_HOLD_S)

    def learn(self, t: float, dt: float, up_force_mean_n: float, against_the_ceiling: bool = False) -> None:
        """Teach the heave effectiveness one cycle: the push of ``rate.age_s`` ago against the range slope now.

        ``against_the_ceiling``: the room's ceiling may be what stops the body (past the ceiling limit after an outage,
        when the watchdog's motors off let it float up), and a window would credit that stop to the pushes: it teaches
        nothing. After a stall, random-2026-27's down side was taught 2.65 there (its truth 0.58), and the hold that
        counted on it swung 0.13 m back over the limit; with a 30 ms reply lag, the light strong corners went up to
        0.40 m over it (docs/flight-robustness.md, session 36)."""
        self._pushes.append((self.push(up_force_mean_n) + self.disturbance, self.disturbance))
        measured = None if self.touched or against_the_ceiling or self.z is None else self.range_rate.rate(t)
        if len(self._pushes) < self._pushes.maxlen:  # type: ignore[operator]
            measured = None
        push, disturbance = self._pushes[0]
        self.effectiveness.update(t, dt, push, measured, learned=disturbance)

    def predict(self, up_force_n: float, dt: float) -> None:
        """Propagate with the modelled forces (thrust, buoyancy, drag)."""
        if self.z is None:
            return
        accel = self.accel(up_force_n)
        self.z += self.vz * dt
        self.vz += accel * dt

    @property
    def bandwidth_hz(self) -> float:
        """How fast the altitude follows the rangefinder: the config's, or a share of it in a held climb on a
        trusted model (``HELD_CLIMB_OBSERVER_SHARE``; ``climbing`` is set by the loop away from the limits). On
        a doubted model the climb keeps the full bandwidth: there the model's error, not the sensor's noise, is
        what the observer must see."""
        if self.climbing and self.c.uncertainty("heave") <= 1.0:
            return self.c.altitude_observer_hz * HELD_CLIMB_OBSERVER_SHARE
        return self.c.altitude_observer_hz

    def update(self, t: float, range_m: float, up_force_n: float, dt: float) -> bool:
        """Fold in one reading; ``True`` when it (re)started the observer rather than corrected it."""
        restarted = self.last_range_t is None or self.reacquire or self.z is None
        self.last_range_t = t
        if restarted:
            self.z, self.vz, self.reacquire = range_m, 0.0, False
            self._restart_t = t
            self.range_rate.clear()
            self._pushes.clear()
            self.range_rate.add(t, range_m)
            return True
        self.range_rate.add(t, range_m)
        self.predict(up_force_n, dt)
        assert self.z is not None
        # The reading is RANGE_LATENCY_S old: compare it with where the body was then.
        residual = range_m - (self.z - self.vz * RANGE_LATENCY_S)
        p = 2.0 * math.pi * self.bandwidth_hz
        q = 2.0 * math.pi * self.c.disturbance_observer_hz
        self.z += (2.0 * p + q) * dt * residual
        self.vz += (p * p + 2.0 * p * q) * dt * residual
        self._correct_climb_rate(t, dt, up_force_n)
        # A sudden large innovation is the body being moved or something passing under the
        # rangefinder, not a buoyancy error: do not learn from it, unless it persists.
        if abs(residual) <= RESIDUAL_GATE_M:
            self._gated_since = None
        elif self._gated_since is None:
            self._gated_since = t
        if self._may_learn(t):
            limit = self.c.altitude_integral_limit
            step = p * p * q * dt * residual / self.effectiveness.value(self.push(up_force_n) + self.disturbance)
            self.disturbance = min(max(self.disturbance + step, -limit), limit)
        return False


class YawEstimate:
    """Heading (the board's, gyro-integrated) and yaw rate (gyro, lightly filtered), plus how strongly
    the body answers a yaw torque.

    The board reports whole degrees. ``fine_heading`` is the gyro's integral pulled toward the board's
    heading over ``FINE_HEADING_TAU_S``: smooth where the board's steps by a degree. The hover heading
    loop's stiffness acts on it; on the board's steps, a degree's worth of stiffness against the damping
    flipped the push's sign several times within 0.3 s (corner-mtDL, session 10).
    """

    def __init__(self, config: FlightConfig) -> None:
        self.c = config
        self.heading: float | None = None
        self.fine_heading: float | None = None
        self.rate_dps = 0.0
        self.last_heading_t: float | None = None
        self._drag_integral = 0.0  # rad/s: the least drag over the flight, added back to the measured rate
        self._least_drag = config.yaw_drag / config.uncertainty("yaw")
        low, high = effectiveness_bounds(config.uncertainty("yaw"), reverse=False)
        self.effectiveness = Effectiveness(low * _yaw_reverse_share(config), high, min_change=0.01,
                                           confirming_change=YAW_CONFIRMING_CHANGE_RAD_S, mirrored=True,
                                           real_pushes_confirm=True, halving_falls=True, one_way=True)

    def update(self, t: float, dt: float, heading_deg: float | None, gyro_dps: float | None, torque_mean: float) -> None:
        if gyro_dps is not None and self.fine_heading is not None:
            self.fine_heading = (self.fine_heading + gyro_dps * dt) % 360.0
        if heading_deg is not None:
            self.heading = heading_deg
            self.last_heading_t = t
            if self.fine_heading is None:
                self.fine_heading = heading_deg
            else:
                miss = (heading_deg - self.fine_heading + 180.0) % 360.0 - 180.0
                self.fine_heading = (self.fine_heading + miss * min(1.0, dt / FINE_HEADING_TAU_S)) % 360.0
        push = torque_mean / self.c.yaw_inertia_kg_m2
        if gyro_dps is not None:
            self.rate_dps += (gyro_dps - self.rate_dps) * min(1.0, dt / YAW_RATE_TAU_S)
        # The air's drag, added back as the surge does, but only the least the box allows: a held turn's torque
        # balances the drag and changes no rate, and read as a push that moved nothing it taught its side the box's
        # weakest (0.20 where the turn had confirmed 1.79); the hover correction after the turn's stop, divided by it,
        # pushed nine times too hard and turned the body back past the stop goal's rate (corner-mTDl, replies 10 ms
        # late: a stop of 1.80 s). With the least drag a held turn reads the truth times (least drag / the plant's) and
        # times what the inertia and thrust are off by: from an eighth to twice the truth across the box, no longer the
        # floor (the drag alone never makes it read strong). The config's drag, twice a low-drag plant's, read a heavy
        # weak corner's turn five times too strong (session 37). A turn held for tens of seconds on a high-drag light
        # plant still drifts its side toward the eighth (docs/flight-robustness.md, session 37).
        r = math.radians(self.rate_dps)
        self._drag_integral += self._least_drag * r * abs(r) / self.c.yaw_inertia_kg_m2 * dt
        self.effectiveness.update(t, dt, push, None if gyro_dps is None else math.radians(gyro_dps) + self._drag_integral)

    def accel(self, torque_nm: float) -> float:
        """The yaw acceleration (rad/s^2) the model and the learned effectiveness give for ``torque_nm`` now."""
        r = math.radians(self.rate_dps)
        push = torque_nm / self.c.yaw_inertia_kg_m2
        return self.effectiveness.value(push) * push - self.c.yaw_drag * r * abs(r) / self.c.yaw_inertia_kg_m2


def _yaw_reverse_share(config: FlightConfig) -> float:
    """A yaw torque is one motor forward, one reversed: the worst reverse ratio costs this share of it."""
    ratio = config.horizontal_reverse_ratio
    worst = ratio / config.uncertainty("yaw")
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
        self.flow_speed = 0.0  # the flow alone, followed within DECISION_FLOW_TAU_S: no model, no drag
        self._flow_tau_s = flow_tau_s(config.uncertainty("surge"))
        self.last_flow_t: float | None = None
        self.last_measured: float | None = None
        self._last_flow_rad_s: float | None = None
        self._flow_noise_var = FLOW_NOISE_RAD_S ** 2  # (rad/s)^2: half the mean square of successive readings' difference
        self._drag_integral = 0.0
        self.bias = 0.0  # m/s^2: what the flow says the model's acceleration misses (see _bias_gain)
        # A model trusted longer than the decision's 0.15 s (a fitted one) has a second state, the acceleration its
        # forces miss: a calibration's deadband 0.02 too wide pushes 0.03 m/s^2 more than modelled at a slow
        # command's small force, and a first-order blend trusting the model for tau is then that times tau off
        # for as long as the command is held (calibrated corner-mTDL, flight seed 5: the estimate at the commanded
        # 0.150 m/s backwards, the body at 0.190, a speed peak of 1.27; session 25). The bias follows the flow's
        # innovation with gain 1/tau^2 (a damping ratio of 0.5 with the blend's 1/tau), so a steady error is gone
        # within about 2 tau. The shipped box's estimate follows the flow within 80 ms and has none: unchanged. Nor
        # has a model trusted outright (uncertainty 1: tau 3 s), which the user says is right: over its 3 s a
        # bias of 0.001 m/s^2 that the flow sensor's own error taught moved the estimate 3 mm/s, and a nominal
        # backward after a forward cruised 2.8 % over its speed (test_onset: 1.9 % without).
        flow_gain = 1.0 / self._flow_tau_s
        self._fitted = DECISION_FLOW_TAU_S < self._flow_tau_s < FLOW_TAU_TRUSTED_S
        self._bias_gain = flow_gain * flow_gain if self._fitted else 0.0
        low, high = effectiveness_bounds(config.uncertainty("surge"), reverse=False)
        reverse_low, _ = effectiveness_bounds(config.uncertainty("surge"), reverse=True)
        # A fitted config whose calibration braked has shown its reverse thrust: until the first brake in flight the
        # speed cap counts on the fit, less one box factor, 1/U (calibrated random-2026-1 cruised at 0.890 of the
        # command on the box's weakest, 1.11^-3 = 0.73, and 0.98 on this). The point estimate itself (1) let
        # corner-MtdL's fitted config take 1.14 s to stop on a plant as weak in reverse as the fit's 3-sigma
        # box allows; 1/U stopped it in 0.90 s (docs/calibrate-flight.md, session 17, branch i13heavy).
        # A calibration that measured its reverse brake directly says how much of the modelled one it showed at 3
        # standard errors low (``surge_brake_shown``): that, not 1/U, is counted on for a forward speed (session 20).
        self.effectiveness = Effectiveness(low, high, reverse_low=reverse_low, min_change=0.005,
                                           assuring_change=SURGE_ASSURING_CHANGE_M_S, confirming_change=SURGE_CONFIRMING_CHANGE_M_S,
                                           shown=1.0 / config.uncertainty("surge") if config.braking_shown else None,
                                           reverse_shown=config.surge_brake_shown or None, real_pushes_assure=True,
                                           one_way=True, assuring_error=SURGE_ASSURING_ERROR)

    def measured(self, t: float) -> bool:
        return self.last_flow_t is not None and t - self.last_flow_t <= FLOW_FRESH_S

    @property
    def flow_noise_rad_s(self) -> float:
        """The flow sensor's noise per reading as measured in flight, never less than ``FLOW_NOISE_RAD_S``.

        Readings a control period apart differ by the noise of both (root 2 times it) and by the body's change of
        speed over height, which at the planned brake is a third of the specified noise at 1.2 m: the measure errs
        noisy, the safe side for what counts on it."""
        return max(FLOW_NOISE_RAD_S, math.sqrt(self._flow_noise_var))

    def update(self, t: float, dt: float, surge_mean_n: float, flow_x_rad_s: float | None, height_m: float | None) -> None:
        c = self.c
        push = surge_mean_n / c.mass_kg
        self.speed += (self.effectiveness.value(push) * push - air_drag(self.speed, c.quadratic_drag) / c.mass_kg + self.bias) * dt
        measured = None
        if flow_x_rad_s is not None and height_m is not None and height_m >= MIN_FLOW_HEIGHT_M:
            self._learn_flow_noise(t, dt, flow_x_rad_s)
            measured = flow_x_rad_s * height_m
            innovation = measured - self.speed
            self.speed += innovation * (1.0 - math.exp(-dt / self._flow_tau_s))
            if self._bias_gain:  # within the planned braking: a bias is a model error or a draft, never a motor
                limit = c.brake_m_s2
                self.bias = min(max(self.bias + self._bias_gain * innovation * dt, -limit), limit)
            # The first reading after a gap restarts the flow-led speed: what its filter held is history, and a
            # held command steers on it (``held_speed``).
            if self.last_flow_t is not None and not self.measured(t):
                self.flow_speed = measured
            else:
                self.flow_speed += (measured - self.flow_speed) * (1.0 - math.exp(-dt / DECISION_FLOW_TAU_S))
            self.last_flow_t, self.last_measured = t, measured
        elif self.bias:
            self.bias *= math.exp(-dt / SURGE_BIAS_FORGET_S)
        # The air's drag brakes the body along with any push against a drift; added back (by the model),
        # it is not credited to the push.
        self._drag_integral += air_drag(self.speed, c.quadratic_drag) / c.mass_kg * dt
        noise = math.sqrt(2.0) * self.flow_noise_rad_s * height_m if measured is not None and height_m is not None else 0.0
        self.effectiveness.update(t, dt, push, None if measured is None else measured + self._drag_integral, noise=noise)

    def _learn_flow_noise(self, t: float, dt: float, flow_rad_s: float) -> None:
        """Fold one reading into the measured noise: only a reading that follows a fresh one counts (after a gap the
        body's speed has changed)."""
        if self._last_flow_rad_s is not None and self.measured(t):
            difference = flow_rad_s - self._last_flow_rad_s
            self._flow_noise_var += (0.5 * difference * difference - self._flow_noise_var) * (1.0 - math.exp(-dt / FLOW_NOISE_TAU_S))
        self._last_flow_rad_s = flow_rad_s

    @property
    def decision_speed(self) -> float:
        """The speed that decides whether the body is still (the hover band): a draft-aware one.

        A fitted model's estimate trusts the model for 0.3-3 s (``flow_tau_s``), and the model knows no
        drafts: its drag decays the modelled speed towards zero while a draft holds the body's, so a
        drift is seen late (corner-mtDL's fitted flight read -2.0 cm/s with the body at -3.8 and the
        flow's mean at -3.2, and a turn's stop took 2.28 s). Whether to correct is therefore decided on
        the flow alone, followed within ``DECISION_FLOW_TAU_S`` (0.15 s: its noise, about 0.5 cm/s, stays
        a sixth of the band's 3 cm/s edge; 0.25 s saw corner-mtDL's drift too late again, 2.26 s). The
        correction itself still uses the estimate, so the flow's noise does not reach the motors. An
        estimate that follows the flow at least as fast (the shipped one: 80 ms) already is that speed
        and is used as it is.
        """
        return self.speed if self._flow_tau_s <= DECISION_FLOW_TAU_S else self.flow_speed

    def held_speed(self, t: float, direction: float) -> float:
        """The speed a held command in ``direction`` is steered on: the estimate, or the flow-led speed when that is
        further along the command.

        A fitted model (trusted for 0.15-3 s: uncertainties of about 1.01-1.47) knows no drafts. A tailwind takes a
        draggy body's drag away while the push stays, and the estimate saw the acceleration a third of a second late:
        calibrated corner-mTDL at flight seed 14 read 0.163 m/s with the body at 0.181, a speed peak of 1.21 (session
        26). The flow alone, followed within ``DECISION_FLOW_TAU_S``, saw more of it. Taken only when it says *faster
        along the command*, its noise can only slow the cruise a little (1-2 mm/s), never push it on. It does reach the
        motors while a command is held: their tick-to-tick change is 39 % larger while the body moves. Taking only the
        flow's lead beyond a margin kept the noise off and gave the peaks back, in proportion (docs/calibrate-flight.md,
        session 26): the speed goal's side of that trade was chosen. The shipped box's estimate already follows the flow
        within 80 ms and a model trusted outright is told to trust its model: both use the estimate. A stale flow
        (``measured``) is not used.
        """
        if self._fitted and self.measured(t) and (self.flow_speed - self.speed) * direction > 0.0:
            return self.flow_speed
        return self.speed

    def accel(self, surge_n: float) -> float:
        """The forward acceleration the model and the learned effectiveness give for ``surge_n`` now."""
        push = surge_n / self.c.mass_kg
        return self.effectiveness.value(push) * push - air_drag(self.speed, self.c.quadratic_drag) / self.c.mass_kg
