"""The scripted flight of `feelium calibrate flight`: small open-loop steps on each axis inside a safe envelope.

A pure policy, ``step(t, telemetry) -> commands``: no clock, no I/O, so the
same script flies the simulator faster than real time and a real board in
real time (``calibrate.py`` is the shell). Between steps a deliberately
simple hold, which needs no model (an altitude PID in command space whose
integral finds the hover command, rate damping on the gyro and the flow),
brings the body back to rest. Each step is one axis's command held for at
most ``seconds``, ended early by the envelope guard: altitude leaving
[``z_low``, ``z_high``], climb rate, forward speed or turn rate over their
caps, or telemetry gone. The other axes keep holding, and every sample,
steps and holds alike, feeds the fit (``feelium/flight/sysid.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from feelium.flight.mixer import NEUTRAL
from feelium.flight.telemetry import Telemetry


@dataclass(frozen=True)
class Envelope:
    """Where the calibration flight may take the blimp."""

    z_low: float = 0.7
    z_high: float = 2.2
    climb_m_s: float = 0.45
    speed_m_s: float = 0.35
    turn_dps: float = 45.0
    telemetry_timeout_s: float = 0.3
    first_telemetry_s: float = 2.0  # a board that has not answered by then is not there: the flight ends at once
    surge_change_m_s: float = 0.2  # a surge step this weak (a heavy, weak plant) is held on, up to its ``extend_s``


@dataclass(frozen=True)
class Step:
    """One excitation: ``axis`` (heave, surge, yaw) at ``level`` for up to ``seconds``, from ``start_z``.

    Heave levels are relative to the learned hover command unless ``absolute``.
    """

    axis: str
    level: float
    seconds: float
    start_z: float = 1.45
    absolute: bool = False
    extend_s: float = 0.0  # surge: longer while the speed has changed by less than ``Envelope.surge_change_m_s``
    only_if_weak: bool = False  # surge: flown only if the pair before it changed the speed by less than that too


# Surge steps at least this large are held on (``extend_s``) while they barely move the body. A smaller push
# (+-0.25, +-0.45: 2-14 % of full thrust past the largest deadband) reaches a terminal speed of a few cm/s on a
# light draggy plant within its 3 s, as small as the drafts; held on, it adds only samples at that speed, where
# the fit ties the push to a drag it underestimates in drafts (the flow sees the ground speed, the drag acts on
# the air speed), and the horizontal deadband came out 27-70 % high (docs/calibrate-flight.md, session 18).
HELD_ON_FROM_LEVEL = 0.6


def default_script() -> list[Step]:
    """About four to five minutes: three sizes each way on surge (the +-0.65 pair held on while it barely moves
    the body: ``extend_s``, from ``HELD_ON_FROM_LEVEL``) and a fourth, +-0.85, only on a plant the +-0.65 pair
    barely moved (``only_if_weak``: on a light plant it is a sub-second step cut short by the speed guard, and
    the light draggy corners' fitted configs cruised 11 % slow with it), three on yaw; on heave steps around
    the hover command (two of them long and gentle, for the drag at steadier speeds), then absolute commands
    through the deadband and into reverse, short, from low down (the body rises fast: buoyancy helps them)."""
    steps: list[Step] = []
    for level in (0.25, 0.45, 0.65, 0.85):
        weak_only, extend = level > 0.7, 3.0 if level >= HELD_ON_FROM_LEVEL else 0.0
        steps += [Step("surge", level, 3.0, extend_s=extend, only_if_weak=weak_only),
                  Step("surge", -level, 3.0, extend_s=extend, only_if_weak=weak_only)]
    for level in (0.2, 0.35, 0.55):
        steps += [Step("yaw", level, 2.5), Step("yaw", -level, 2.5)]
    for delta, seconds in ((0.12, 2.5), (0.25, 2.0), (0.06, 4.0)):
        steps += [Step("heave", delta, seconds, start_z=1.9), Step("heave", -delta, seconds, start_z=1.0)]
    for level, seconds in ((0.0, 1.2), (0.15, 1.2), (0.3, 1.5), (-0.3, 0.8), (-0.6, 0.6), (-0.9, 0.5)):
        steps.append(Step("heave", level, seconds, start_z=0.9, absolute=True))
    steps.append(Step("heave", 0.95, 1.5, start_z=2.0, absolute=True))
    return steps


@dataclass(frozen=True)
class HoldGains:
    """The model-free hold between steps, in command units (gentle: the blimp may be 2x off the config)."""

    altitude_p: float = 0.35  # command per m above target (push down)
    altitude_d: float = 0.6  # command per m/s climbing
    altitude_i: float = 0.12  # command per m s
    speed_d: float = 1.2  # command per m/s forward
    yaw_d: float = 0.5  # differential command per rad/s
    deadband_guess: float = 0.06
    settle_s: float = 6.0
    settle_max_s: float = 9.0


@dataclass
class CalibrationPilot:
    """Hold, step, hold, step... then neutral. ``done`` once the script is flown or aborted."""

    hover_command: float
    script: list[Step] = field(default_factory=default_script)
    envelope: Envelope = field(default_factory=Envelope)
    gains: HoldGains = field(default_factory=HoldGains)
    z: float | None = None
    w: float = 0.0
    u: float = 0.0
    r: float = 0.0
    done: bool = False
    aborted: str | None = None
    index: int = -1  # the step being flown or settled for; -1 the first settle
    phase: str = "settle"
    segments: list[tuple[int, float, float]] = field(default_factory=list)  # (step index, start t, end t)
    surge_changes: dict[int, float] = field(default_factory=dict)  # surge step index -> its speed change in ``seconds``
    skipped: list[int] = field(default_factory=list)  # ``only_if_weak`` steps not flown: the plant was brisk
    _phase_t: float | None = None
    _last_t: float | None = None
    _last_telemetry_t: float | None = None
    _first_t: float | None = None  # the first tick's time: a board silent from the start times out from there
    _integral: float = 0.0
    _z_ref: float = 1.45
    _step_u: float = 0.0  # the forward speed when the step began
    _step_change: float = 0.0  # the largest |speed - _step_u| within the step's ``seconds`` (before any hold-on)

    def abort(self, reason: str) -> None:
        """Stop the script at once: motors neutral from the next step on."""
        self.aborted, self.done = reason, True

    def step(self, t: float, telemetry: Telemetry | None) -> tuple[float, float, float, float]:
        """The four motor commands for this control tick."""
        dt = 0.02 if self._last_t is None else max(t - self._last_t, 1e-3)
        self._last_t = t
        self._absorb(t, dt, telemetry)
        if self.done:
            return NEUTRAL
        if self._first_t is None:
            self._first_t = t
        if self._last_telemetry_t is None:
            if t - self._first_t > self.envelope.first_telemetry_s:
                self.abort("no telemetry: the board never answered")
            return NEUTRAL
        if t - self._last_telemetry_t > self.envelope.telemetry_timeout_s:
            self.abort("telemetry lost")
            return NEUTRAL
        if self._phase_t is None:
            self._phase_t = t
        hold = self._hold(dt)
        if self.phase == "settle":
            if self._settled(t):
                self._next_step(t)
            return hold
        step = self.script[self.index]
        if t - self._phase_t <= step.seconds:  # not the hold-on: it runs until the change reaches the threshold
            self._step_change = max(self._step_change, abs(self.u - self._step_u))
        if t - self._phase_t >= self._duration(step) or self._outside(step):
            self.segments.append((self.index, self._phase_t, t))
            if step.axis == "surge":
                self.surge_changes[self.index] = self._step_change
            self.phase, self._phase_t = "settle", t
            self._z_ref = self._next_start_z()
            return hold
        return self._excite(step, hold)

    # ---- sensing ----
    def _absorb(self, t: float, dt: float, tel: Telemetry | None) -> None:
        if tel is None:
            return
        fresh = False
        if tel.range_m is not None:
            if self.z is None:
                self.z = tel.range_m
            else:  # alpha-beta filter: altitude and climb rate from the rangefinder alone
                predicted = self.z + self.w * dt
                residual = tel.range_m - predicted
                self.z = predicted + 0.4 * residual
                self.w += 3.0 * residual
            fresh = True
        if tel.yaw_rate_dps is not None:
            self.r += (math.radians(tel.yaw_rate_dps) - self.r) * min(1.0, dt / 0.05)
            fresh = True
        if tel.flow_x_rad_s is not None and self.z is not None:
            self.u += (tel.flow_x_rad_s * self.z - self.u) * min(1.0, dt / 0.05)
        if fresh:
            self._last_telemetry_t = t

    # ---- the hold ----
    def _hold(self, dt: float) -> tuple[float, float, float, float]:
        g = self.gains
        z = self.z if self.z is not None else self._z_ref
        error = float(np.clip(z - self._z_ref, -0.3, 0.3))
        self._integral = float(np.clip(self._integral + g.altitude_i * error * dt, -0.3, 0.3))
        vertical = float(np.clip(self.hover_command + self._integral + g.altitude_p * error + g.altitude_d * self.w, -0.5, 0.95))
        surge = self._compensated(-g.speed_d * self.u)
        yaw = self._compensated(-g.yaw_d * self.r)
        return (float(np.clip(surge + yaw, -0.5, 0.5)), float(np.clip(surge - yaw, -0.5, 0.5)), vertical, vertical)

    def _compensated(self, command: float) -> float:
        """A small command lifted over a typical deadband, faded in so it does not chatter around zero."""
        blend = min(1.0, abs(command) / 0.03)
        return math.copysign(abs(command) + self.gains.deadband_guess * blend, command) if command else 0.0

    def _settled(self, t: float) -> bool:
        assert self._phase_t is not None
        elapsed = t - self._phase_t
        if elapsed >= self.gains.settle_max_s:
            return True
        z = self.z if self.z is not None else self._z_ref
        still = abs(z - self._z_ref) < 0.08 and abs(self.w) < 0.04 and abs(self.u) < 0.03 and abs(self.r) < math.radians(2.0)
        return elapsed >= self.gains.settle_s * (0.5 if self.index >= 0 else 1.0) and still

    def _next_step(self, t: float) -> None:
        self.index = self._following()
        if self.index >= len(self.script):
            self.done = True
            return
        self.phase, self._phase_t, self._step_u, self._step_change = "step", t, self.u, 0.0

    def _following(self) -> int:
        """The next step to fly after the current one, recording the ``only_if_weak`` ones passed over."""
        following = self.index + 1
        while following < len(self.script) and not self._flies(following):
            if following not in self.skipped:
                self.skipped.append(following)
            following += 1
        return following

    def _flies(self, index: int) -> bool:
        """An ``only_if_weak`` step flies only if either of the last two unconditional surge steps flown (the
        pair before it) changed the speed by less than ``surge_change_m_s`` in its ``seconds`` (it needed its
        hold-on): the plant needs the bigger push. With no surge step measured yet it flies (nothing says brisk)."""
        if not self.script[index].only_if_weak:
            return True
        before = [i for i in sorted(self.surge_changes) if i < index and not self.script[i].only_if_weak][-2:]
        return not before or min(self.surge_changes[i] for i in before) < self.envelope.surge_change_m_s

    def _next_start_z(self) -> float:
        following = self._following()
        return self.script[following].start_z if following < len(self.script) else self._z_ref

    # ---- the steps ----
    def _excite(self, step: Step, hold: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        left, right, front, rear = hold
        if step.axis == "surge":
            yaw = (left - right) / 2.0
            return (step.level + yaw, step.level - yaw, front, rear)
        if step.axis == "yaw":
            return (step.level, -step.level, front, rear)
        vertical = step.level if step.absolute else self.hover_command + self._integral + step.level
        return (left, right, vertical, vertical)

    def _duration(self, step: Step) -> float:
        """How long this step runs: a surge step that has barely changed the speed (a heavy, weak plant, where a
        reverse step at a fixed length drowned in the drafts and left the reverse ratio +-30 %) is held on."""
        weak = step.axis == "surge" and abs(self.u - self._step_u) < self.envelope.surge_change_m_s
        return step.seconds + (step.extend_s if weak else 0.0)

    def _outside(self, step: Step) -> bool:
        e = self.envelope
        z = self.z if self.z is not None else self._z_ref
        if step.axis == "heave":
            return not e.z_low <= z <= e.z_high or abs(self.w) > e.climb_m_s
        if step.axis == "surge":
            return abs(self.u) > e.speed_m_s
        return abs(math.degrees(self.r)) > e.turn_dps

