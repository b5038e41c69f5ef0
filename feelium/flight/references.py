"""The references the loops follow: smooth targets, rate-command onsets and braking ramps.

Pure numerical pieces shared by the altitude, heading and surge loops; each
is a few lines of state advanced by ``dt``, so each is tested alone.
"""

from __future__ import annotations

import math

HANDOVER_S = 0.15  # time constant of the last part of a rate onset, where full thrust hands over to the rate loop
# What a cycle of no time (a repeated timestamp) divides by when there is no handover taper either: the command is
# then the full acceleration towards the target, or none on it, as in a cycle, never a division by zero.
NO_TIME_S = 1e-9


def wrap_deg(angle: float) -> float:
    """An angle difference folded into [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


class Reference:
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


class RateOnset:
    """The reference a rate command (forward, up, turn...) follows from its first cycle.

    A step in the reference rate asked for only gain x rate error at onset, well
    short of what the motors can give, so the body got going late. This
    reference instead models the body as the controller's feed-forward will
    move it: its acceleration follows the commanded one through the motor lag
    (``lag_s``, the config's ``motor_lag_s``). The command is the largest acceleration the actuators
    allow (``limits``) until the reference's *lag-aware predicted* rate
    (``rate + accel x lag``: where it ends up if the command went to zero now)
    comes within ``HANDOVER_S`` of the commanded rate, then tapers
    exponentially. The predicted rate moves exactly at the commanded
    acceleration, so it never passes the commanded rate, and the rate itself,
    which trails it by the lag, does not either. ``handover_s`` is that taper's
    time constant; 0 lands the predicted rate on the target within a cycle
    (a turn brake: the rate then tapers through the lag alone).
    """

    def __init__(self, lag_s: float, handover_s: float = HANDOVER_S) -> None:
        self.lag_s = lag_s
        self.handover_s = handover_s
        self.rate = 0.0
        self.accel = 0.0  # after the motor lag

    def start(self, rate: float, accel: float) -> None:
        """Begin from the body's present rate and (modelled) acceleration, so nothing jumps."""
        self.rate, self.accel = rate, accel

    @property
    def predicted(self) -> float:
        return self.rate + self.accel * self.lag_s

    def step(self, target: float, limits: tuple[float, float], dt: float) -> tuple[float, float, float]:
        """This cycle's reference (rate, predicted rate, acceleration command); then advance over ``dt``."""
        rate, predicted = self.rate, self.predicted
        lo, hi = min(limits[0], 0.0), max(limits[1], 0.0)
        command = min(max((target - predicted) / max(self.handover_s, dt, NO_TIME_S), lo), hi)
        decay = math.exp(-dt / self.lag_s)  # the command held over dt through the lag, exactly
        self.rate += command * dt + (self.accel - command) * self.lag_s * (1.0 - decay)
        self.accel = command + (self.accel - command) * decay
        return rate, predicted, command


def ramp_to_zero(rate: float, decel: float, dt: float) -> tuple[float, float]:
    """One step of a constant-deceleration ramp from ``rate`` to zero: (new rate, acceleration)."""
    step = decel * dt
    if abs(rate) <= step:
        return 0.0, -rate / dt if dt > 0 else 0.0
    return rate - math.copysign(step, rate), -math.copysign(decel, rate)


def stoppable_rate(decel: float, within_s: float, lag_s: float, stopped_below: float) -> float:
    """The fastest rate a body braking at ``decel`` after a ``lag_s`` dead time gets under ``stopped_below`` within ``within_s``."""
    return stopped_below + decel * max(within_s - lag_s, 0.0)
