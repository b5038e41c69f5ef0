"""In hover a horizontal motor keeps its direction for a while: no audible back-and-forth.

The hover bands (``loops.py``) keep each loop from reversing its own push, but
a motor serves two loops (surge plus or minus yaw), so their sum can still
flip sign every time either loop re-engages: on an untuned blimp in mild
drafts that was 0.7-1.1 direction changes a second, each one a propeller
stopping and spinning up the other way (noise, wear, and a thrust the model
gets wrong while the ESC reverses). In calm hover, and only there, a motor that
spun one way is not reversed until ``MIN_INTERVAL_S`` has passed: it waits at
neutral, and the air's drag does the rest. Calm hover means both loops have
been hovering (no command, brake or settling) for ``SETTLE_S`` and the body
is still by the stop goal's measure, with a margin. Once it moves faster, or
at any command, brake or stop, the guard steps aside at once: a correction
that matters always has full authority. (Holding a reversal while the body is
still moving was tried: holding one motor of the pair at neutral unbalances the
yaw torque, and a heavy blimp's stop after a lapsed turn took 1.8 s, not 0.9.)

While one motor of the pair waits at neutral, the other is rebalanced so that
the pair keeps the yaw torque the loops asked for, and gives up the surge push
instead (``PairThrust``). Holding one motor alone turned a surge correction into
a yaw kick: on corner-mTdL a hover correction of (+0.27, held) swung the yaw
rate from -0.9 to +3.4 deg/s, past the calm threshold, and the heading loop's
answer reversed both motors (session 10). In calm hover the speed is under
4.5 cm/s, so a surge correction that waits costs little; a yaw kick costs
reversals. Yaw wins over surge, as in the mixer.

While the body is *still* (under ``CALM_SPEED_M_S``) but turning faster than
calm, a motor that would reverse *alone* waits as in calm hover, its partner
keeping the torque (session 16, docs/calibrate-flight.md): that is a surge push
against the motor holding the yaw torque (on the light strong corners a
saturated one, reversing the torque's motor at each engagement: corner-mTDL). Both
motors reversing is the torque itself turning, and goes through.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from feelium.flight.mixer import command_for_thrust, thrust_for_command

MIN_INTERVAL_S = 2.5  # at most one reversal per 2.5 s per motor: 0.4/s, under the 0.5/s goal
# Calm: slower than this, the body counts as still (inside the stop goal's 5 cm/s and 3 deg/s, with a margin).
CALM_SPEED_M_S = 0.045
CALM_YAW_DPS = 2.5
SETTLE_S = 3.0  # after a command or a brake, this long with full authority first


@dataclass(frozen=True)
class PairThrust:
    """The horizontal pair's thrust curve as the config describes it: command <-> force (N)."""

    max_thrust_n: float
    reverse_ratio: float
    deadband: float

    def force(self, command: float) -> float:
        return thrust_for_command(command, self.max_thrust_n, self.reverse_ratio, self.deadband)

    def command(self, force_n: float) -> float:
        return command_for_thrust(force_n, self.max_thrust_n, self.reverse_ratio, self.deadband)


def calm(speed_m_s: float, yaw_rate_dps: float) -> bool:
    """Still enough that a correction may wait: a faster body is corrected at once, reversal or not."""
    return abs(speed_m_s) < CALM_SPEED_M_S and abs(yaw_rate_dps) < CALM_YAW_DPS


class ReversalGuard:
    """Per horizontal motor: the direction it last spun and when it took that direction."""

    def __init__(self, pair: PairThrust | None = None) -> None:
        """``pair``: the thrust curve that rebalances a held motor's partner (``None``: the partner is left as it is)."""
        self._pair = pair
        self._sign = [0.0, 0.0]  # the horizontal pair: the mixer's first two motors
        self._since = [-math.inf, -math.inf]
        self._hovering_since = math.inf
        self.held = 0  # cycles in which a motor was kept from reversing, for health

    def limit(self, t: float, commands: tuple[float, float, float, float], hovering: bool, calm: bool,
              still: bool | None = None) -> tuple[float, float, float, float]:
        """``commands`` with each horizontal motor that would reverse too soon at neutral: only while the
        body has been ``hovering`` for ``SETTLE_S`` (the settling after a command or a brake keeps full
        authority) and is ``calm``, or is ``still`` (slower than ``CALM_SPEED_M_S``, whatever its yaw rate;
        default: ``calm``) and only one motor of the pair would reverse."""
        if not hovering:
            self._hovering_since = math.inf
        elif self._hovering_since == math.inf:
            self._hovering_since = t
        settled = t - self._hovering_since >= SETTLE_S
        reversing = [commands[i] != 0.0 and self._sign[i] != 0.0 and math.copysign(1.0, commands[i]) != self._sign[i] for i in range(2)]
        # One motor reversing alone is the surge push against the motor that holds the yaw torque (the
        # partner keeps the torque below); both reversing is the torque itself turning, which only calm waits.
        quiet = settled and (calm or (calm if still is None else still) and reversing[0] != reversing[1])
        out = list(commands)
        for i in range(2):
            if commands[i] == 0.0:
                continue  # neutral: no direction taken. Any other command may spin the motor: the real
                # deadband is unknown and may be far below the config's (a motor inside the config's
                # deadband flipping every few cycles was most of the reversals on such blimps).
            wanted = math.copysign(1.0, commands[i])
            if wanted == self._sign[i]:
                continue
            if reversing[i] and quiet and t - self._since[i] < MIN_INTERVAL_S:
                out[i] = 0.0
                continue
            self._sign[i], self._since[i] = wanted, t
        if out[:2] != list(commands[:2]):
            self.held += 1
            if self._pair is not None and (out[0] == 0.0) != (out[1] == 0.0):
                other = 0 if out[1] == 0.0 else 1
                out[other] = self._balanced(commands[other], commands[1 - other])
        return out[0], out[1], out[2], out[3]

    def _balanced(self, command: float, held: float) -> float:
        """The command for a held motor's partner that keeps the pair's yaw torque (left minus right
        force): the partner's force less the held motor's. Neutral if that would reverse the partner too."""
        assert self._pair is not None
        force = self._pair.force(command)
        balanced = force - self._pair.force(held)
        return self._pair.command(balanced) if balanced * force > 0.0 else 0.0
