"""The three loops: altitude, heading and surge, each from its estimate and setpoint to one force.

Every loop works in accelerations and turns them into a force with the
config's mass (or inertia) divided by the learned effectiveness, so the same
gains hold on a blimp twice as heavy or half as strong. A rate command
(forward, up, turn) starts through a :class:`RateOnset`, is capped at the
rate the body can still stop from within ``stop_within_s`` (counting only on
the braking it has shown, or the box's weakest until it has braked once),
and on release brakes along a ramp (a turn: a reference that lands on zero
through the box's longest motor lag), then holds where the body came to rest.
In hover the horizontal loops rest inside a small band instead of chasing
sensor noise, so the horizontal motors do not reverse back and forth.
"""

from __future__ import annotations

import math

from feelium.flight.config import Axis, FlightConfig
from feelium.flight.estimators import YAW_RATE_TAU_S, AltitudeObserver, SurgeEstimate, ThrustModel, YawEstimate, air_drag
from feelium.flight.mixer import Mixer
from feelium.flight.references import (
    HANDOVER_S,
    RateOnset,
    Reference,
    ramp_to_zero,
    stoppable_rate,
    wrap_deg,
)
from feelium.flight.setpoint import Setpoint

SETTLE_S = 0.6  # damping-only phase after a braking ramp
RECOVERY_SETTLE_S = 2.5  # damping-only phase after telemetry returns from an outage
# Back from an outage outside the altitude limits, the hold's target is the limit moved this far inside, not the limit:
# the watchdog's motors off let the body float to the room's ceiling, and the descent back is flown on a heave side no
# window has taught, whose first readings may be anything in the box (docs/flight-robustness.md, session 36). Held at
# the limit itself, every bounce of that descent counted against the limits' 10 cm; ArduPilot's fence likewise
# recovers to a point inside its fence, not onto it.
RECOVERY_MARGIN_M = 0.2
# ...and a recovery ends once the body has stayed inside the limits this long (or at the next vertical command): a
# shove past a limit minutes later is a hold's to correct, not an outage's.
RECOVERY_CLEAR_S = 10.0
REST_MEAN_TAU_S = 0.15  # the averaging of where a settling stop rests: a few range readings, less than its settling
SETTLE_DAMPING = 6.0  # its damping, (m/s^2) per m/s and (rad/s^2) per rad/s
STOPPED_SPEED_M_S = 0.05  # the stop goal's thresholds (docs/flight-robustness.md)
STOPPED_YAW_DPS = 3.0
BRAKE_SHARE = 0.55  # of the full reverse authority a stop may count on (the rest: drag, the other loop, slew)
# ...and while it counts on a brake the calibration measured, at 3 standard errors low (``surge_brake_shown``): the
# uncertainty is then in the brake counted on, not in the share. 0.8 stopped the heavy weak corners (seeds 1-4)
# within 0.62 s on their true plants and 0.94 s on plants as weak in reverse as that low end; a share of 1.0 (on
# the larger of 1/U and that low end) took 1.00 s (docs/calibrate-flight.md, session 20).
MEASURED_BRAKE_SHARE = 0.8
# A hover correction counts on its side's learned surge value, but no less than the other side's value over this:
# corrections holding against a draft change no speed and teach their side weak (corner-mTDl's reverse side read 0.12,
# its forward 0.25, where the truth was about 2 and 4), and a 5 cm/s drift was met at full forward, then full reverse,
# past the hover's reversal goal (flight seeds 56-57). What fixed those flights is mostly the untaught side: the surge
# is not mirrored, so a side no window has taught is the box's strongest (4) and every correction counts on at least
# 4 / 2 until both sides are taught; counting on the other side only once taught left both flights missing. The price
# (the session-31 review): heavy weak corners whose hover teaches one side only hold their place more loosely (drift
# 0.13-0.20 -> 0.20-0.30 m), which no safety goal measures. With the larger side's value whole, 7 of 1152 flights
# missed a goal where 3 had (docs/flight-robustness.md, session 31).
HOVER_SIDES_APART = 2.0
HOVER_SPEED_BAND_M_S = 0.02  # in hover the surge loop rests below this measured speed (acts above 0.03)...
HOVER_YAW_BAND_DPS = 1.0  # ...and the heading loop below this yaw rate (and within the heading tolerance)
# The hover heading loop takes over above this yaw rate. A draft keeps turning a light blimp through the filtered gyro's
# lag and a long-lag motor's: engaged at 2 deg/s, rates went on to 3.0-3.6 deg/s, over the stop goal's 3, and stops
# and lapses failed (corner-mTDL flight seeds 8 and 10: 2.78 s, 2.30 s; docs/flight-robustness.md, session 23).
HOVER_ENGAGE_YAW_DPS = 1.5 * HOVER_YAW_BAND_DPS
HOVER_FIRM_YAW_DPS = 2.0 * HOVER_YAW_BAND_DPS  # above it a hover's damping takes the full gain (see HeadingLoop.step)
HOVER_GAIN = 0.5  # a hover correction is gentle: it must not overshoot into a correction the other way
# A turn brake's reference is done once its predicted rate is this close to zero and its rate inside the hover band.
BRAKE_LANDED_DPS = 0.3
# A hover heading correction turns back at most this fast: the stop goal's yaw rate with the turn cap's margin. The
# stiffness balances the damping at kp/kd (0.94 deg/s per degree), so a heading 5 deg off after a forward turned back
# at 3.04-3.10 deg/s, seconds after a stop that was otherwise complete (corner-MtDL seed 2, MtdL seed 3; session 20).
HOVER_RETURN_DPS = 0.7 * STOPPED_YAW_DPS
# A turn whose sign nothing has confirmed yet halves the yaw effectiveness it is normalised by every this long, from the
# box's strongest down to the learned value: on a heavy weak blimp the box's strongest is 20 times its answer, and a
# turn normalised by it reached 0.05-0.17 of the command, too little ever to confirm one (session 21). A held
# command's surge push and a hover heading correction whose sign nothing has taught escalate alike (session 24).
ESCALATE_S = 0.3
MIN_CLIMB_BRAKE_M_S2 = 0.02  # a body that shows no braking at all still gets a finite (very slow) approach
STILL_M_S = 0.05  # a climb rate this small is holding still: its force is the hover force...
HOVER_FORCE_TAU_S = 2.0  # ...averaged over this long
LIMIT_BRAKE_SHARE = 0.35  # of the vertical authority a climb into a limit plans to brake with (the loop needs the rest)


def recovery_target(config: FlightConfig, z: float, target: float | None = None) -> float:
    """Where a hold at ``z`` recovering from an outage aims: inside the altitude limits ``target`` (``z`` if none),
    else the limit ``z`` is past moved ``RECOVERY_MARGIN_M`` inside (at most a quarter of the span between the limits),
    or ``target`` if that is further inside: a recovery moves a hold inward, never outward."""
    low, high = config.altitude_min_m, config.altitude_max_m
    margin = min(RECOVERY_MARGIN_M, 0.25 * (high - low))
    held = z if target is None else target
    if z > high:
        return min(held, high - margin)
    if z < low:
        return max(held, low + margin)
    return held


def longest_lag_s(config: FlightConfig, axis: Axis) -> float:
    """The longest motor lag (time constant) the axis' box allows: the config's, times the axis' uncertainty."""
    return config.motor_lag_s * config.uncertainty(axis)


def escalated(high: float, pushing_s: float) -> float:
    """The effectiveness an untaught push is normalised by after ``pushing_s``: the box's strongest ``high``, halved
    every ``ESCALATE_S`` (the caller keeps it at or above what was learned, or the box's weakest)."""
    return high * 0.5 ** (pushing_s / ESCALATE_S)


def worst_lag_s(config: FlightConfig, axis: Axis) -> float:
    """The longest motor lag the axis' box allows, plus a cycle and the flow sensor's frame: what a stop must wait out."""
    return longest_lag_s(config, axis) + 0.1


class _Band:
    """Hysteresis for a hover loop: engage when the error leaves the band, rest once it is well inside.

    Inside the band the push keeps the sign it last had outside (the other sign rests instead):
    a correction that overshoots a little is left to the air's drag, not answered by reversing
    the motors, which in hover is what made the horizontal pair reverse several times a second.
    Outside the band the loop acts either way.
    """

    def __init__(self) -> None:
        self.engaged = True
        self.outside = True
        self.sign = 0.0

    def release(self) -> None:
        self.engaged, self.sign = False, 0.0

    def take_over(self) -> None:
        """Outside hover (a command, a brake): the loop acts, and remembers no hover sign."""
        self.engaged, self.sign = True, 0.0

    def update(self, outside: bool, well_inside: bool) -> bool:
        self.outside = outside
        if outside:
            self.engaged = True
        elif well_inside:
            self.release()
        return self.engaged

    def same_sign(self, push: float) -> float:
        """``push``, or 0 when inside the band it would reverse the direction it had."""
        if (self.outside or self.sign == 0.0) and push != 0.0:
            self.sign = math.copysign(1.0, push)
        return push if push * self.sign >= 0.0 else 0.0


class AltitudeLoop:
    """Altitude hold, climb and descent on the rangefinder, with the net buoyancy as feed-forward."""

    def __init__(self, config: FlightConfig, mixer: Mixer) -> None:
        self.c, self.mixer = config, mixer
        self.target: float | None = None
        self.ref = Reference(2.0 * math.pi * config.reference_hz)
        self.climbing = False
        self.onset = RateOnset(config.motor_lag_s)
        self.braking = False
        self.settle_until: float | None = None
        self.rest_z: float | None = None  # the altitude's recent mean while a stop settles
        self.up_n = -config.net_buoyancy_n
        self.hover_up_n = -config.net_buoyancy_n  # the force that held the body still, lately
        self.near_limit = False  # a climb slowed for a limit: its braking is planned on the weakest plant
        self.saturated_t = -math.inf  # the last cycle the vertical force was at a motor limit
        self.recovering = False  # back from an outage, until the next vertical command: see ``recovery_target``
        self.inside_since: float | None = None  # while recovering, since when the body is inside the limits

    def restart(self, z: float) -> None:
        """Hold here from now on (first reading, or back from a failsafe)."""
        self.target = z
        self.ref.reset(z)
        self.recovering = False

    def let_go(self, z: float) -> None:
        """A partner let go of the body at ``z``: hold there, or, in a recovery, where the recovery aims (a hand that
        held the body past a limit during one does not end it)."""
        recovering = self.recovering
        self.restart(recovery_target(self.c, z) if recovering else z)
        self.recovering = recovering

    def recover(self, t: float) -> None:
        """Back from an outage, probably drifting: damp it out, then hold where it comes to rest (inside the limits,
        and a margin inside them if it drifts past one: ``recovery_target``)."""
        self.climbing = self.braking = False
        self.settle_until, self.rest_z = t + RECOVERY_SETTLE_S, None
        self.recovering, self.inside_since = True, None

    def step(self, t: float, dt: float, sp: Setpoint, obs: AltitudeObserver, thrust: ThrustModel, gain: float, soft: bool) -> float:
        c = self.c
        z = obs.z
        assert z is not None and self.target is not None
        ref = self.ref
        self._end_a_long_recovery(t, z)
        climb = 0.0 if soft else sp.climb_m_s
        rate_ahead = 0.0
        if climb:
            if not self.climbing:
                self.onset.start(obs.vz, obs.accel(thrust.vertical))
            self.climbing = True
            self.recovering = False
            target = self._climb_within_limits(z, obs, climb)
            ref.rate, rate_ahead, ref.accel = self.onset.step(target, self._accel_limits(obs, self.onset.rate), dt)
            ahead = min(max(ref.value + ref.rate * dt, z - 0.25), z + 0.25)
            ref.value = min(max(ahead, c.altitude_min_m), c.altitude_max_m)
            self.target = ref.value
        elif self.climbing:
            # Just released: decelerate along a planned ramp from the present climb rate, then hold.
            self.climbing = False
            ref.reset(z, obs.vz)
            self.braking = True
        # A held climb flies on its rate alone, but past a limit the limit is a position to hold.
        p_gain = 0.0 if climb and c.within_altitude_limits(z) else 1.0
        # Away from the limits a held climb on a trusted model may filter the range noise harder; near one the
        # observer keeps its full bandwidth, where a wrong model's lag would carry the body past the limit.
        obs.climbing = bool(climb) and not self.near_limit
        if not climb and self.braking:
            ref.rate, ref.accel = ramp_to_zero(ref.rate, c.brake_climb_m_s2, dt)
            ref.value += ref.rate * dt
            self.target = ref.value
            if ref.rate == 0.0:
                self.braking, self.settle_until, self.rest_z = False, t + SETTLE_S, None
        elif not climb and self.settle_until is not None and c.within_altitude_limits(z):
            # Damp out what is left and hold where it comes to rest, never outside the limits. Where it rests is the
            # altitude's recent mean, not its last estimate: one range-noisy cycle 1 cm low became the hold's
            # target, and the body, stopped 0.3 s after a released `up`, then sank 1 cm at 2.5 cm/s two seconds
            # later (the flight bench's `up` stop, 0.44 -> 2.40 s, was that sink crossing 10 % of the climb rate).
            p_gain, gain = 0.0, gain * SETTLE_DAMPING / max(c.altitude_kd, 1e-6)
            self.rest_z = z if self.rest_z is None else self.rest_z + (z - self.rest_z) * min(1.0, dt / REST_MEAN_TAU_S)
            # A mean lags a still-moving body by its speed times the averaging time: brought forward by it.
            rest = min(max(self.rest_z + obs.vz * REST_MEAN_TAU_S, c.altitude_min_m), c.altitude_max_m)
            ref.reset(rest)
            self.target = rest
            if t >= self.settle_until:
                self.settle_until = self.rest_z = None
        elif not climb:
            self.settle_until = self.rest_z = None  # outside the limits a settling stop holds the limit at once
            if sp.altitude_m is not None:
                self.target, self.recovering = sp.altitude_m, False
            if self.recovering:
                self.target = recovery_target(c, z, self.target)
            self.target = min(max(self.target, c.altitude_min_m), c.altitude_max_m)
            ref.advance(self.target - ref.value, dt)
        error = min(max(ref.value - z, -c.altitude_error_limit_m), c.altitude_error_limit_m)
        rate_ref = rate_ahead if climb else ref.rate
        predicted = obs.vz + obs.accel(thrust.vertical) * c.motor_lag_s
        wanted = gain * (p_gain * c.altitude_kp * error + c.altitude_kd * (rate_ref - predicted)) + ref.accel
        brake = ref.accel if self.near_limit and climb * ref.accel < 0.0 else 0.0  # the climb slowing for a limit
        push = self._limit_brake_push(brake, obs) + (wanted - brake) / self._effectiveness(obs, z, climb, wanted - brake) - obs.disturbance
        up_n = c.heave_mass * push - c.net_buoyancy_n + c.quadratic_drag * ref.rate * abs(ref.rate)
        lo, hi = self.mixer.limits_up_n()
        saturated = up_n >= hi or up_n <= lo
        # Anti-windup: the disturbance (the integral) learns only while the loop is in charge: not
        # saturated, not softened by a partner, and not far *below* its target (a partner holding the
        # body down must not wind it up into a lunge when let go). Far *above* it still learns: a weak
        # blimp pinned under the ceiling must learn to push down harder, and up is where it fails safe.
        # Nor, in a held climb or descent, for the box's longest motor lag after a saturated cycle: the motors are
        # still catching up with the limit, and what the model misses then is its lag's error, not a force: a
        # calibrated heavy corner (lag 150 ms, fitted 106 ms) climbing on and off its down limit learned +0.3 m/s^2
        # in 9 s (truth about 0.01), modelled no braking left, and rose through the ceiling limit and on through
        # the `down` after it (corner-MtdL, flight seed 3; docs/calibrate-flight.md, session 22). A hold learns at
        # once: heavy corners hover near their motors' limit, and waiting there too left the shipped config's
        # altitude excursions on them at 0.08-0.09 m where they were 0.01-0.03.
        if saturated:
            self.saturated_t = t
        settling = bool(climb) and t - self.saturated_t < longest_lag_s(c, "heave")
        below = max(ref.value - z, self.target - z) > c.altitude_integral_band_m
        obs.freeze_disturbance = soft or saturated or settling or below
        obs.touched = soft or below
        self.up_n = min(max(up_n, lo), hi)
        if not climb and abs(obs.vz) < STILL_M_S:
            self.hover_up_n += (self.up_n - self.hover_up_n) * min(1.0, dt / HOVER_FORCE_TAU_S)
        return self.up_n

    def recovering_over_the_ceiling(self, z: float | None) -> bool:
        """Back from an outage with the body past the ceiling limit, where the room's ceiling may be what stops it."""
        return self.recovering and z is not None and z > self.c.altitude_max_m

    def _end_a_long_recovery(self, t: float, z: float) -> None:
        """A recovery ends once the body has stayed inside the limits for ``RECOVERY_CLEAR_S``."""
        if not self.recovering:
            return
        if not self.c.within_altitude_limits(z):
            self.inside_since = None
        elif self.inside_since is None:
            self.inside_since = t
        elif t - self.inside_since >= RECOVERY_CLEAR_S:
            self.recovering = False

    def _effectiveness(self, obs: AltitudeObserver, z: float, climb: float, push: float) -> float:
        """What a push is divided by: the learned effectiveness, but the assured one for a push back inside the
        limits (a hold's, or a held climb's whose reference waits at the limit: corner-mtDl s32, session 24). The learned value of a side starts at the box's strongest (push gently), which below the floor
        is the unsafe way: a weak heavy-drag blimp released under `altitude_min` believed its up push 2.2 times the
        model, pushed a tenth of what it needed and sank 12 cm under the limit (corner-mtDl, flight seed 8)."""
        c = self.c
        inward = (z < c.altitude_min_m and push > 0.0) or (z > c.altitude_max_m and push < 0.0)
        if inward:
            return min(obs.effectiveness.value(push), obs.effectiveness.assured(push))
        return obs.effectiveness.value(push)

    def _limit_brake_push(self, brake: float, obs: AltitudeObserver) -> float:
        """The push that slows a climb for a limit: the planned deceleration on the weakest plant of the box.

        Divided by the learned effectiveness like the rest, it was a quarter of the plan on a plant whose
        braking direction had not been learned yet (the estimate starts at the box's strongest), and the
        body reached the limit at most of its climb rate (random-2026-17: 10 cm through the ceiling). A
        stronger plant brakes harder on it and stops short of the limit, the safe side; the push is capped
        at the share of the headroom the plan counted on.
        """
        if brake == 0.0:
            return 0.0
        c = self.c
        lo, hi = self.mixer.limits_up_n()
        share = LIMIT_BRAKE_SHARE * abs((lo if brake < 0.0 else hi) - self.hover_up_n) / c.heave_mass
        return math.copysign(min(abs(brake) / obs.effectiveness.lowest(brake), share), brake)

    def _climb_within_limits(self, z: float, obs: AltitudeObserver, climb: float) -> float:
        """The commanded climb rate, slowed near the altitude limits so that a held up or down stops there."""
        c = self.c
        z_ahead = z + obs.vz * (HANDOVER_S + longest_lag_s(c, "heave"))
        room = c.altitude_max_m - z_ahead if climb > 0 else z_ahead - c.altitude_min_m
        allowed = math.sqrt(2.0 * self._braking(obs, climb) * max(room, 0.0))
        self.near_limit = allowed < abs(climb)
        return math.copysign(min(abs(climb), allowed), climb)

    def _braking(self, obs: AltitudeObserver, climb: float) -> float:
        """The deceleration a climb (or a descent) at the limit may plan on: a quarter of the planned
        brake, or what this body has shown it can do with a share of its authority, if that is less
        (a heavy blimp whose motors barely hold its buoyancy stops a climb slowly). The authority is
        the headroom between the force that holds it still and the motors' limit: both are commands
        the loop really sent, so the buoyancy error cancels."""
        c = self.c
        lo, hi = self.mixer.limits_up_n()
        toward = -1.0 if climb > 0 else 1.0
        headroom = ((lo if climb > 0 else hi) - self.hover_up_n) / c.heave_mass
        shown = toward * obs.effectiveness.assured(toward) * headroom
        return max(min(0.25 * c.brake_climb_m_s2, LIMIT_BRAKE_SHARE * shown), MIN_CLIMB_BRAKE_M_S2)

    def _accel_limits(self, obs: AltitudeObserver, rate: float) -> tuple[float, float]:
        c = self.c
        lo, hi = self.mixer.limits_up_n()
        drag = air_drag(rate, c.quadratic_drag)
        e = obs.effectiveness
        down = (lo + c.net_buoyancy_n - drag) / c.heave_mass + obs.disturbance
        up = (hi + c.net_buoyancy_n - drag) / c.heave_mass + obs.disturbance
        # A reference slows, or turns, at least at the braking the limits' plan counts on (``_braking``: from the
        # commands that held the body still, so no disturbance enters it): the disturbance a heavy corner's hold
        # learns may leave the model no braking at all, and a reference clipped to what the model allows held a
        # climb into the limit, or on through a `down`: with the disturbance's wait above and without this floor,
        # corner-Mtdl on the shipped config left the altitude limits by 0.14 m (flight seed 2; session 22).
        return min(e.value(down) * down, -self._braking(obs, 1.0)), max(e.value(up) * up, self._braking(obs, -1.0))


class HeadingLoop:
    """Heading hold and turns on the gyro, normalised by the learned yaw effectiveness."""

    def __init__(self, config: FlightConfig, mixer: Mixer) -> None:
        self.c, self.mixer = config, mixer
        self.target: float | None = None
        self.ref = Reference(2.0 * math.pi * config.reference_hz)
        self.turning = False
        self.onset = RateOnset(config.motor_lag_s)
        # The turn brake's reference: full deceleration until its rate predicted over the box's longest lag lands on
        # zero (no handover taper: its own lag is the taper), so no reverse torque is left in a long lag's pipe.
        self.brake = RateOnset(longest_lag_s(config, "yaw"), handover_s=0.0)
        self.braking = False
        self.settle_until: float | None = None
        self.band = _Band()
        self.hovering = False  # no command, no brake, no settling: the motors may be kept from reversing
        self.turn_cap_dps = config.yaw_rate_dps
        self.turn_started = 0.0
        self.untaught_push_since: float | None = None  # a hover correction of an untaught sign pushes since then...
        self.untaught_push_sign = 0.0  # ...this way
        self.escalating = False  # this cycle's push has a sign nothing taught (confirmed): it escalates (health)
        self.firm_against_rate = False  # a hover correction or a settle braking a rate over the firm one (see ``step``)
        self.settling_a_brake = False  # the settle follows a turn's brake, not a telemetry outage (see ``step``)

    def restart(self, heading: float) -> None:
        self.target = heading
        self.ref.reset(heading)

    def recover(self, t: float) -> None:
        self.turning = self.braking = self.settling_a_brake = False
        self.settle_until = t + RECOVERY_SETTLE_S

    def step(self, t: float, dt: float, sp: Setpoint, est: YawEstimate, thrust: ThrustModel, gain: float) -> float:
        c = self.c
        self.escalating = self.firm_against_rate = False
        if est.heading is None or self.target is None:
            return 0.0
        ref = self.ref
        self.turn_cap_dps = self._stoppable_dps(est)
        turn = 0.0 if sp.soften else math.copysign(min(abs(sp.yaw_rate_dps), self.turn_cap_dps), sp.yaw_rate_dps)
        rate_ahead = 0.0
        if turn:
            if not self.turning:
                self.onset.start(math.degrees(self._rate_now(est, thrust)), math.degrees(est.accel(thrust.yaw)))
                self.turn_started = t
            self.turning = True
            ref.rate, rate_ahead, ref.accel = self.onset.step(turn, self._accel_limits_dps2(est, self.onset.rate), dt)
            ahead = wrap_deg(ref.value + ref.rate * dt - est.heading)
            ref.value = (est.heading + min(max(ahead, -20.0), 20.0)) % 360.0
            self.target = ref.value
        elif self.turning:
            self.turning = False
            ref.reset(est.heading, est.rate_dps)
            self.brake.start(math.degrees(self._rate_now(est, thrust)), math.degrees(est.accel(thrust.yaw)))
            self.braking = True
        p_gain = 0.0 if turn else 1.0
        hover = settling = False
        if not turn and self.braking:
            ref.rate, rate_ahead, ref.accel = self.brake.step(0.0, (-c.brake_yaw_dps2, c.brake_yaw_dps2), dt)
            ref.value = (ref.value + ref.rate * dt) % 360.0
            self.target = ref.value
            if abs(rate_ahead) < BRAKE_LANDED_DPS and abs(ref.rate) < HOVER_YAW_BAND_DPS:
                self.braking, self.settle_until, self.settling_a_brake = False, t + SETTLE_S, True
        elif not turn and self.settle_until is not None:
            settling = True
            p_gain, gain = 0.0, gain * SETTLE_DAMPING / max(c.heading_kd, 1e-6)
            ref.reset(est.heading)
            self.target = est.heading
            if t >= self.settle_until:
                self.settle_until = None
        elif not turn:
            hover = sp.heading_deg is None
            if sp.heading_deg is not None:
                self.target = sp.heading_deg % 360.0
            ref.advance(wrap_deg(self.target - ref.value), dt)
            ref.value %= 360.0
        # In hover the stiffness acts on the gyro-smoothed heading: the board's whole degrees made the
        # stiffness jump by a degree's worth against the damping, flipping the push's sign (docs/flight-robustness.md).
        error_deg = wrap_deg(ref.value - (est.fine_heading if hover and est.fine_heading is not None else est.heading))
        self.hovering = hover
        if hover:
            tolerance = c.hover_heading_tolerance_deg
            outside = abs(wrap_deg(self.target - est.heading)) > tolerance or abs(est.rate_dps) > HOVER_ENGAGE_YAW_DPS
            inside = abs(wrap_deg(self.target - est.heading)) < 0.5 * tolerance and abs(est.rate_dps) < HOVER_YAW_BAND_DPS
            if not self.band.update(outside, inside):
                self.untaught_push_since = None
                return 0.0
            # Near the stop goal's rate a hover's damping takes the full gain: halved, a light blimp in drafts was held
            # at 3 deg/s, not under it (flight seed 14: stops that never completed). From 1.5 deg/s on, where the loop
            # takes over, it made the motors reverse 0.6 times a second on two of the 50 random plants (session 23).
            firm = 1.0 / HOVER_GAIN if abs(est.rate_dps) > HOVER_FIRM_YAW_DPS else 1.0  # the damping's share of it
            gain *= HOVER_GAIN
        else:
            self.band.take_over()
            self.untaught_push_since = None  # a hover correction after this starts its escalation afresh
            firm = 1.0
        error = math.radians(min(max(error_deg, -45.0), 45.0))
        predicted = math.radians(est.rate_dps) + est.accel(thrust.yaw) * (YAW_RATE_TAU_S + self._lag_s(turn))
        rate_error = math.radians(rate_ahead if turn or self.braking else ref.rate) - predicted
        alpha = gain * (p_gain * c.heading_kp * error + firm * c.heading_kd * rate_error) + math.radians(ref.accel)
        if hover and error:
            alpha = self._limit_return(alpha, error, predicted, gain)
        r_ref = math.radians(ref.rate)
        effectiveness = self._hover_effectiveness(t, alpha, est) if hover else self._turn_effectiveness(t, alpha, est, turn)
        torque = c.yaw_inertia_kg_m2 * alpha / effectiveness + c.yaw_drag * r_ref * abs(r_ref)
        if hover:
            torque = self.band.same_sign(torque)
            self.firm_against_rate = not sp.soften and firm > 1.0 and torque * est.rate_dps < 0.0
        elif settling and self.settling_a_brake:
            # A brake lands on its plan, not on the body: on a plant whose deadband is twice the config's, the settle
            # took over at 8 deg/s and its push, compensated for the config's deadband, was mostly eaten (the rate
            # crept to 3 deg/s in 0.6 s: corner-mTdl's stops took 0.98 s at flight seeds 8 and 38, 0.88-0.90 mixed so).
            # Not after a telemetry outage: that settle starts from a full turn's rate with a long lag's torque still
            # in the pipe, and mixed so it swung past zero to -3.25 deg/s (corner-mTdL, a 0.4 s stall; the review).
            self.firm_against_rate = not sp.soften and abs(est.rate_dps) > HOVER_FIRM_YAW_DPS and torque * est.rate_dps < 0.0
        return torque

    def _lag_s(self, turn: float) -> float:
        """The lag the body's rate is predicted over: in a turn and its brake the box's longest, as the brake plans.

        A brake over the config's 80 ms lag left the reverse torque of a 150 ms plant in the pipe as the rate reached
        zero: the rate went on to +4 deg/s the other way (corner-mTdL, lapses up to 1.50 s). A held turn over it let
        the rate outrun its reference through the longer lag, to 1.23 of the command on the same corner (flight seeds
        4, 7, 19, 23, 24; session 24). Elsewhere the config's:
        the settling's and the hover's small pushes, predicted over the longest lag, counted on torque a deadband
        larger than the config's had eaten and let the rate linger near the stop threshold (lapses 1.84-2.02 s;
        docs/flight-robustness.md, session 22)."""
        return longest_lag_s(self.c, "yaw") if turn or self.braking else self.c.motor_lag_s

    def _hover_effectiveness(self, t: float, alpha: float, est: YawEstimate) -> float:
        """What a hover correction is normalised by: the learned value, or for a sign no window has taught (on this
        mirrored axis, neither sign), the box's strongest halving every ``ESCALATE_S`` while the correction keeps
        pushing that way. The box's strongest is the gentle side, but on a plant whose deadband is the box's widest
        the gentle push was eaten whole: nothing moved, so nothing taught it, and a draft turned corner-mTDl past the
        stop goal's rate while the loop pushed (flight seed 17: a stop 1.40 s) and carried corner-Mtdl's heading 15
        deg off through its hover (flight seed 25; docs/flight-robustness.md, session 24)."""
        e = est.effectiveness
        if e.is_taught(alpha) or not alpha:
            self.untaught_push_since = None
            return e.value(alpha)
        sign = math.copysign(1.0, alpha)
        if self.untaught_push_since is None or sign != self.untaught_push_sign:
            self.untaught_push_since, self.untaught_push_sign = t, sign
        self.escalating = True
        return max(e.lowest(alpha), escalated(e.high, t - self.untaught_push_since))

    def _turn_effectiveness(self, t: float, alpha: float, est: YawEstimate, turn: float) -> float:
        """What a large push (a turn, its brake) is normalised by: the confirmed value, or during a turn whose sign
        nothing has confirmed, the box's strongest halving every ``ESCALATE_S`` down to the learned value (the
        safe side first, never below what the small pushes taught).

        A brake whose sign nothing has confirmed goes on with its turn's escalation, counting on what the turn
        reached. Counting on the box's strongest, 20 times the plant's answer, a heavy weak blimp's first turn (too
        slow ever to confirm) was braked at 0.4 of the motors where a confirmed brake pushed 0.9, and its rate was
        still 7 deg/s when the brake's reference landed (corner-MtDL, flight seed 36: a stop 1.46 s; session 27).
        Its escalation stops at the larger value either sign learned (the axis is mirrored): hover pushes a wide
        deadband ate teach the brake's side far below the truth, and a brake counting on that pushed up to seven
        times too hard (the turn's own side is taught by the turn; docs/flight-robustness.md, session 28)."""
        e = est.effectiveness
        self.escalating = (bool(turn) or self.braking) and not e.is_confirmed(alpha)
        if not self.escalating:
            return e.confirmed(alpha)
        learned = max(e.value(alpha), e.value(-alpha)) if self.braking else e.value(alpha)
        return max(learned, escalated(e.high, t - self.turn_started))

    @staticmethod
    def _limit_return(alpha: float, error: float, predicted: float, gain: float) -> float:
        """A hover correction's acceleration, at most what holds the return toward the target at ``HOVER_RETURN_DPS``.

        The stiffness balances the damping at kp/kd, so a heading far off came back faster than the stop goal's
        yaw rate. Only a push *toward* the target is limited, to a damping as firm as the settling's toward that
        rate: it brakes a return that is too fast, and leaves the correction of a heading within about 4 deg of the
        target as it was, and a push against a drift away grows with the drift's rate. (A clipped stiffness, or a
        reference kept within the tolerance of the heading, let the drafts carry an unlearned heading 28 deg off.)"""
        toward = math.copysign(1.0, error)
        limit = gain * SETTLE_DAMPING * (math.radians(HOVER_RETURN_DPS) - toward * predicted)
        return toward * limit if toward * alpha > limit else alpha

    def _rate_now(self, est: YawEstimate, thrust: ThrustModel) -> float:
        """The yaw rate (rad/s) now: the filtered gyro brought forward over its filter lag."""
        return math.radians(est.rate_dps) + est.accel(thrust.yaw) * YAW_RATE_TAU_S

    def _stoppable_dps(self, est: YawEstimate) -> float:
        c = self.c
        torque = self.mixer.limit_yaw_nm() * BRAKE_SHARE
        decel = math.degrees(min(est.effectiveness.assured(1.0), est.effectiveness.assured(-1.0)) * torque / c.yaw_inertia_kg_m2)
        decel = min(decel, c.brake_yaw_dps2)
        return min(c.yaw_rate_dps, stoppable_rate(decel, c.stop_within_s, worst_lag_s(c, "yaw"), 0.7 * STOPPED_YAW_DPS))

    def _accel_limits_dps2(self, est: YawEstimate, rate_dps: float) -> tuple[float, float]:
        c = self.c
        r = math.radians(rate_dps)
        torque, drag = self.mixer.limit_yaw_nm(), c.yaw_drag * r * abs(r)
        return (math.degrees((-torque * est.effectiveness.value(-1.0) - drag) / c.yaw_inertia_kg_m2),
                math.degrees((torque * est.effectiveness.value(1.0) - drag) / c.yaw_inertia_kg_m2))


class SurgeLoop:
    """Forward speed on the measured speed (optical flow), normalised by the learned surge effectiveness."""

    def __init__(self, config: FlightConfig, mixer: Mixer) -> None:
        self.c, self.mixer = config, mixer
        self.ref_speed = 0.0
        self.surging = False
        self.onset = RateOnset(config.motor_lag_s)
        self.band = _Band()
        self.hovering = False  # no command, no brake, no settling: the motors may be kept from reversing
        self.speed_cap = config.forward_speed_m_s
        self.command_started = 0.0
        self.escalating_since = 0.0  # an untaught push escalates from the later of this (an outage's end) and the start
        self.escalating = False  # this cycle's push has a sign nothing taught (confirmed): it escalates (health)

    def step(self, t: float, dt: float, speed_sp: float, gain: float, est: SurgeEstimate, thrust: ThrustModel) -> float:
        c = self.c
        self.escalating = False
        self.speed_cap = self._stoppable_speed(t, est, speed_sp)
        speed_sp = math.copysign(min(abs(speed_sp), self.speed_cap), speed_sp) if speed_sp else 0.0
        hover = False
        if speed_sp:
            if not self.surging:
                self.onset.start(est.speed, est.accel(thrust.surge))
                self.command_started = t
            self.surging = True
            self.ref_speed, v_ahead, accel = self.onset.step(speed_sp, self._accel_limits(est, self.onset.rate), dt)
        else:  # released: brake along a ramp the reverse thrust can follow
            self.surging = False
            self.ref_speed, accel = ramp_to_zero(min(self.ref_speed, est.speed, key=abs), c.brake_m_s2, dt)
            v_ahead = self.ref_speed
            hover = self.ref_speed == 0.0 and est.measured(t)  # the hover band needs a measured speed
        self.hovering = not speed_sp and self.ref_speed == 0.0  # no command, braking done
        if hover:
            speed = est.decision_speed
            if not self.band.update(abs(speed) > 1.5 * HOVER_SPEED_BAND_M_S, abs(speed) < HOVER_SPEED_BAND_M_S):
                return 0.0
        else:
            self.band.take_over()
        v = self.ref_speed
        # While a command is held the speed is predicted over the box's longest lag: the push a 150 ms motor still owes
        # after the config's 80 ms carried strong light corners to 1.23 of the commanded speed (flight seeds 4-5), with
        # the push already at zero. The brake and the hover keep the config's lag (predicted over the longest, a
        # hover's small pushes counted on thrust a wide deadband had eaten; session 22).
        lag = longest_lag_s(c, "surge") if speed_sp else c.motor_lag_s
        speed = est.held_speed(t, speed_sp) if speed_sp else est.speed
        predicted = speed + est.accel(thrust.surge) * lag
        wanted = accel + gain * c.speed_kp * (v_ahead - predicted)
        if speed_sp:
            effectiveness = self._command_effectiveness(t, wanted, est)
        elif hover:
            effectiveness = max(est.effectiveness.value(wanted), est.effectiveness.value(-wanted) / HOVER_SIDES_APART)
        else:
            effectiveness = est.effectiveness.value(wanted)
        force = c.mass_kg * wanted / effectiveness + air_drag(v, c.quadratic_drag)
        return self.band.same_sign(force) if hover else force

    def _command_effectiveness(self, t: float, wanted: float, est: SurgeEstimate) -> float:
        """What a held command's push is normalised by: the confirmed value (windows that changed the speed as a command
        or a brake does) once one has confirmed its sign, never below the learned value (so never a harder push than
        the learned value asks), else the box's strongest halving every ``ESCALATE_S`` down to the learned value, from
        the command's start or the end of a telemetry outage, whichever is later: a correction against the command
        after a dropped link, escalating from a start 4.8 s past, was at once divided by a value the outage's noisy
        windows had taught the box's weakest, and pushed full reverse then full forward (corner-mtdL: 1.445 of the
        command; docs/flight-robustness.md, session 33). Restarting it whenever the push changed sign weakened the
        corrections of a noisy cruise and so the brake after it (the session-33 review). The learned value is taught
        by every window, and a steady push through a deadband wider than the config's reads weak: corner-mTDL's forward
        side was learned at 1.40 where its commands had confirmed 4.0, and a later command's onset, counting on 1.40,
        ran the body to 1.19 of the command (flight seed 19; 1.13 counting on the confirmed value;
        docs/flight-robustness.md, session 28).

        The first windows of a command on a 150 ms, deadband-wide plant see the push and not yet its answer: they
        taught corner-mTdL's forward side the box's weakest (0.25 against about 4) in 0.2 s, the push went to the
        motors' limit, and the body reached 1.25 of the command (flight seed 9; docs/flight-robustness.md, session 24)."""
        e = est.effectiveness
        self.escalating = not e.is_confirmed(wanted)
        if not self.escalating:
            return max(e.confirmed(wanted), e.value(wanted))
        return max(e.value(wanted), escalated(e.high, t - max(self.command_started, self.escalating_since)))

    def recover(self, t: float) -> None:
        """Back from a telemetry outage: what the outage taught is suspect, so an untaught push escalates afresh."""
        self.escalating_since = t

    def _stoppable_speed(self, t: float, est: SurgeEstimate, speed_sp: float) -> float:
        """The fastest speed this blimp has shown it can stop from in time (reverse thrust for forward): on a share of
        its braking authority, larger while that braking is the low end of what a calibration measured."""
        c = self.c
        lo, hi = self.mixer.limits_surge_n()
        braking = -1.0 if speed_sp >= 0 else 1.0
        measured = braking < 0.0 and c.surge_brake_shown > 0.0 and est.effectiveness.counts_on_shown(braking)
        braking_n = (-lo if speed_sp >= 0 else hi) * (MEASURED_BRAKE_SHARE if measured else BRAKE_SHARE)
        effectiveness = est.effectiveness.assured(braking)
        decel = min(effectiveness * braking_n / c.mass_kg, c.brake_m_s2 * 2.0)
        cap = min(c.forward_speed_m_s, stoppable_rate(decel, c.stop_within_s, worst_lag_s(c, "surge"), 0.7 * STOPPED_SPEED_M_S))
        if not est.measured(t):
            cap *= c.no_flow_speed_fraction
        return cap

    def _accel_limits(self, est: SurgeEstimate, speed: float) -> tuple[float, float]:
        c = self.c
        lo, hi = self.mixer.limits_surge_n()
        drag = air_drag(speed, c.quadratic_drag)
        return ((lo * est.effectiveness.value(-1.0) - drag) / c.mass_kg, (hi * est.effectiveness.value(1.0) - drag) / c.mass_kg)
