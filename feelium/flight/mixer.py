"""From forces to four motor commands, gently.

Geometry (``docs/flight.md``): motors 1 and 2 are horizontal, left and right
of the centre line at ``arm_m``, pushing forward for positive commands;
their sum drives surge, their difference yaw. Motors 3 and 4 are vertical
(front and rear) and push the body *down* for positive commands, since their
steady job is to cancel the net buoyancy. Commands are in [-1, 1];
the board maps them to 1000..2000 us with 1500 as no thrust. Each pair has
its own reverse thrust: the horizontal pair runs reversible 3D propellers
(nearly as strong backward as forward), the vertical pair one-direction ones
(``propellers.py``).

Quiet flight is the point: thrust grows with the square of the command, so
the mixer inverts that curve (linear force response, no jerks near zero),
blends its deadband compensation in smoothly instead of jumping, clips
magnitudes, and limits how fast any command may change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from feelium.flight import messages as m

NEUTRAL: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # command space; to_microseconds maps it to messages.NEUTRAL_MOTORS_US


@dataclass(frozen=True)
class MixerGeometry:
    arm_m: float
    horizontal_thrust_n: float
    vertical_thrust_n: float
    horizontal_reverse_ratio: float  # reverse thrust / forward thrust, per pair (propellers.py)
    vertical_reverse_ratio: float
    deadband: float
    max_output: float
    slew_per_s: float


def command_for_thrust(force_n: float, max_thrust_n: float, reverse_ratio: float, deadband: float) -> float:
    """The motor command that makes ``force_n`` (negative: reverse) under a quadratic thrust curve."""
    limit = max_thrust_n if force_n >= 0 else max_thrust_n * reverse_ratio
    if limit <= 0 or force_n == 0:
        return 0.0
    fraction = min(1.0, abs(force_n) / limit)
    blend = min(1.0, fraction / 0.01)  # deadband compensation fades in over the first 1 % of thrust
    magnitude = deadband * blend + (1.0 - deadband) * math.sqrt(fraction)
    return math.copysign(magnitude, force_n)


def thrust_for_command(command: float, max_thrust_n: float, reverse_ratio: float, deadband: float) -> float:
    """The inverse of :func:`command_for_thrust` (used by the speed observer)."""
    magnitude = abs(command)
    if magnitude <= deadband:
        return 0.0
    fraction = min(1.0, (magnitude - deadband) / (1.0 - deadband))
    thrust = max_thrust_n * fraction * fraction
    return thrust if command > 0 else -thrust * reverse_ratio


class Mixer:
    """Surge force, vertical force and yaw torque to four slew-limited commands."""

    def __init__(self, geometry: MixerGeometry) -> None:
        self.g = geometry
        self.last: tuple[float, float, float, float] = NEUTRAL
        self.saturated_vertical = 0
        self.saturated_horizontal = 0

    def reset(self, commands: tuple[float, float, float, float] = NEUTRAL) -> None:
        self.last = commands

    def split(self, surge_n: float, up_n: float, yaw_nm: float) -> tuple[float, float, float, float]:
        """Per-motor forces (left, right, front-down, rear-down), within what the motors can do.

        When the horizontal pair cannot give both, yaw wins over surge: a
        blimp that cannot turn is worse than one that cannot hurry.
        """
        g = self.g
        fwd, rev = g.horizontal_thrust_n * g.max_output**2, g.horizontal_thrust_n * g.horizontal_reverse_ratio * g.max_output**2
        half_diff = yaw_nm / (2.0 * g.arm_m)
        max_diff = (fwd + rev) / 2.0
        if abs(half_diff) > max_diff:
            half_diff = math.copysign(max_diff, half_diff)
        lo, hi = -rev + abs(half_diff), fwd - abs(half_diff)
        half_surge = min(max(surge_n / 2.0, lo), hi)
        if half_surge != surge_n / 2.0 or abs(half_diff) == max_diff:
            self.saturated_horizontal += 1
        v_fwd, v_rev = g.vertical_thrust_n * g.max_output**2, g.vertical_thrust_n * g.vertical_reverse_ratio * g.max_output**2
        down_each = -up_n / 2.0
        clipped = min(max(down_each, -v_rev), v_fwd)
        if clipped != down_each:
            self.saturated_vertical += 1
        return half_surge + half_diff, half_surge - half_diff, clipped, clipped

    def limits_surge_n(self) -> tuple[float, float]:
        """The smallest (full reverse) and largest total surge force of the horizontal pair, without yaw."""
        g = self.g
        return -2 * g.horizontal_thrust_n * g.horizontal_reverse_ratio * g.max_output**2, 2 * g.horizontal_thrust_n * g.max_output**2

    def limit_yaw_nm(self) -> float:
        """The largest yaw torque either way: one horizontal motor full forward, the other full reverse."""
        g = self.g
        return g.horizontal_thrust_n * (1.0 + g.horizontal_reverse_ratio) * g.max_output**2 * g.arm_m

    def limits_up_n(self) -> tuple[float, float]:
        """The smallest and largest total upward motor force (before buoyancy)."""
        g = self.g
        return -2 * g.vertical_thrust_n * g.max_output**2, 2 * g.vertical_thrust_n * g.vertical_reverse_ratio * g.max_output**2

    def mix(self, surge_n: float, up_n: float, yaw_nm: float, dt: float,
            horizontal_deadband: float | None = None) -> tuple[float, float, float, float]:
        """Commands in [-max_output, max_output], each changed by at most ``slew_per_s * dt``; the horizontal motors'
        deadband compensated as ``horizontal_deadband`` if given, else as the geometry's."""
        forces = self.split(surge_n, up_n, yaw_nm)
        g = self.g
        band = g.deadband if horizontal_deadband is None else horizontal_deadband
        wanted = (
            command_for_thrust(forces[0], g.horizontal_thrust_n, g.horizontal_reverse_ratio, band),
            command_for_thrust(forces[1], g.horizontal_thrust_n, g.horizontal_reverse_ratio, band),
            command_for_thrust(forces[2], g.vertical_thrust_n, g.vertical_reverse_ratio, g.deadband),
            command_for_thrust(forces[3], g.vertical_thrust_n, g.vertical_reverse_ratio, g.deadband),
        )
        return self.limit(wanted, dt)

    def limit(self, wanted: tuple[float, ...], dt: float) -> tuple[float, float, float, float]:
        """Each command clipped to ``max_output``, then moved at most ``slew_per_s * dt`` from the last one.

        Written out with comparisons instead of ``min(max(...))`` (it runs every tick); each picks what
        the builtins would, ties and NaN included: ``max(a, b)`` is ``b if b > a else a``, ``min(a, b)``
        is ``b if b < a else a``.
        """
        step = self.g.slew_per_s * (0.0 if 0.0 > dt else dt)
        top = self.g.max_output
        bottom = -top
        out = []
        for previous, target in zip(self.last, wanted):
            target = bottom if bottom > target else target
            target = top if top < target else target
            low, high = previous - step, previous + step
            target = low if low > target else target
            out.append(high if high < target else target)
        self.last = (out[0], out[1], out[2], out[3])
        return self.last


def to_microseconds(commands: tuple[float, ...]) -> tuple[int, ...]:
    """Commands in [-1, 1] to MSP motor values around the 1500 us neutral."""
    low, high, neutral = m.MOTOR_MIN_US, m.MOTOR_MAX_US, m.MOTOR_NEUTRAL_US
    return tuple(int(low if us <= low else high if us >= high else us) for us in [round(neutral + 500.0 * c) for c in commands])
