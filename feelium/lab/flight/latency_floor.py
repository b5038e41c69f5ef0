"""How soon the body *can* be moving after a command: the physical floor under command-to-motion latency.

Whatever the controller does, the motors answer through a first-order lag
and reverse thrust may be weaker than forward thrust. Two floors per command,
both from rest in a hover and measured with the scenarios' thresholds
(2 cm/s, 3 deg/s):

- ``closed_form_s``: the whole available force change at once, through the
  lag alone: v(t) = (F/m)(t - tau(1 - e^(-t/tau))) reaches the threshold at
  this time. No controller can beat it.
- ``slew_limited_s``: the blimp model (``blimp_model.step`` at the simulated
  board's physics step) driven with the largest commands the mixer allows,
  each changed no faster than the slew limit per control period: the best a
  controller with these quietness limits can do.

The bench reports both next to the measured latency, and the same numbers
for the hardware the spec rules out, one-direction propellers on the
horizontal pair, as a what-if: that is the reason for the spec.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from feelium.flight import blimp_model as bm
from feelium.flight.config import FlightConfig
from feelium.flight.sim_board import PHYSICS_DT
from feelium.flight.mixer import command_for_thrust
from feelium.flight.propellers import ONE_DIRECTION_REVERSE_RATIO
from feelium.lab.flight.scenarios import MOTION_THRESHOLD as THRESHOLD


@dataclass(frozen=True)
class LatencyFloor:
    command: str
    accel: float  # available acceleration from a hover, m/s^2 or deg/s^2
    closed_form_s: float
    slew_limited_s: float


def lag_response_time(accel: float, threshold: float, tau: float) -> float:
    """When v(t) = accel (t - tau (1 - e^(-t/tau))), a step of force through a first-order lag, reaches ``threshold``."""
    if accel <= 0.0:
        return math.inf
    if tau <= 0.0:
        return threshold / accel
    lo, hi = 0.0, 1.0
    while accel * (hi - tau * (1.0 - math.exp(-hi / tau))) < threshold:
        lo, hi = hi, hi * 2.0
        if hi > 1e6:
            return math.inf
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if accel * (mid - tau * (1.0 - math.exp(-mid / tau))) < threshold:
            lo = mid
        else:
            hi = mid
    return hi


def one_direction_horizontal_propellers(
    config: FlightConfig, blimp: bm.BlimpParams | None = None, reverse_ratio: float = ONE_DIRECTION_REVERSE_RATIO
) -> tuple[FlightConfig, bm.BlimpParams]:
    """The what-if the hardware spec rules out: the horizontal pair on one-direction propellers
    (60 % reverse thrust), in the controller's knowledge and in the simulated body alike.
    Nothing else changes (the vertical pair has one-direction propellers either way)."""
    blimp = blimp or bm.BlimpParams()
    return (
        replace(config, horizontal_reverse_ratio=reverse_ratio),
        replace(blimp, horizontal_motor=replace(blimp.horizontal_motor, reverse_ratio=reverse_ratio)),
    )


def _targets(name: str, limit: float) -> tuple[float | None, float | None, float | None, float | None]:
    """The commands a command asks for at full authority (``None``: the motor keeps its hover command)."""
    return {
        "forward": (limit, limit, None, None),
        "backward": (-limit, -limit, None, None),
        "up": (0.0, 0.0, -limit, -limit),
        "down": (0.0, 0.0, limit, limit),
        "turn_right": (limit, -limit, None, None),
        "turn_left": (-limit, limit, None, None),
    }[name]


def _signal(name: str, state: bm.BlimpState) -> float:
    return {
        "forward": state.u,
        "backward": -state.u,
        "up": state.w,
        "down": -state.w,
        "turn_right": math.degrees(state.r),
        "turn_left": -math.degrees(state.r),
    }[name]


def _slew_limited(name: str, config: FlightConfig, blimp: bm.BlimpParams, seconds: float = 0.5) -> float:
    vertical = blimp.vertical_motor
    hover_each = blimp.net_buoyancy_n / 2.0
    hover = command_for_thrust(hover_each, vertical.max_thrust_n, vertical.reverse_ratio, vertical.deadband)
    state = bm.BlimpState(z=1.2, thrust_n=(0.0, 0.0, hover_each, hover_each))
    commands = [0.0, 0.0, hover, hover]
    wanted = [hover if t is None else t for t in _targets(name, config.max_output)]
    step = config.slew_per_s / config.rate_hz
    substeps = max(1, round(1.0 / config.rate_hz / PHYSICS_DT))
    threshold = THRESHOLD[name]
    t, previous = 0.0, 0.0
    while t < seconds:
        commands = [min(max(w, c - step), c + step) for c, w in zip(commands, wanted)]
        for _ in range(substeps):
            state = bm.step(blimp, state, (commands[0], commands[1], commands[2], commands[3]), PHYSICS_DT)
            value = _signal(name, state)
            if value > threshold:
                return t + PHYSICS_DT * (threshold - previous) / (value - previous)
            t, previous = t + PHYSICS_DT, value
    return math.inf


def available_accel(name: str, config: FlightConfig, blimp: bm.BlimpParams) -> float:
    """The acceleration change full authority gives from a hover (m/s^2; deg/s^2 for turns)."""
    h, v = blimp.horizontal_motor, blimp.vertical_motor
    full = config.max_output
    mass = blimp.inertial_mass_kg
    if name == "forward":
        return 2 * h.static_thrust(full) / mass
    if name == "backward":
        return -2 * h.static_thrust(-full) / mass
    if name == "up":  # from cancelling the buoyancy to full reverse (up) thrust
        return (blimp.net_buoyancy_n - 2 * v.static_thrust(-full)) / mass
    if name == "down":
        return (2 * v.static_thrust(full) - blimp.net_buoyancy_n) / mass
    torque = (h.static_thrust(full) - h.static_thrust(-full)) * blimp.arm_m
    return math.degrees(torque / blimp.yaw_inertia_kg_m2)


def latency_floor(name: str, config: FlightConfig, blimp: bm.BlimpParams | None = None) -> LatencyFloor:
    blimp = blimp or bm.BlimpParams()
    tau = blimp.horizontal_motor.time_constant_s if name not in ("up", "down") else blimp.vertical_motor.time_constant_s
    accel = available_accel(name, config, blimp)
    return LatencyFloor(name, accel, lag_response_time(accel, THRESHOLD[name], tau), _slew_limited(name, config, blimp))
