"""The reversal guard: in calm hover a horizontal motor keeps its direction for MIN_INTERVAL_S, never otherwise."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.flight.reversal import (
    CALM_SPEED_M_S,
    CALM_YAW_DPS,
    MIN_INTERVAL_S,
    SETTLE_S,
    PairThrust,
    ReversalGuard,
    calm,
)


def _settled_guard() -> ReversalGuard:
    """Hovering since 0, the motors last took their direction at SETTLE_S (then 0.3, -0.3)."""
    guard = ReversalGuard()
    guard.limit(0.0, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=True)
    assert guard.limit(SETTLE_S, (0.3, -0.3, 0.5, 0.5), hovering=True, calm=True) == (0.3, -0.3, 0.5, 0.5)
    return guard


def test_in_calm_hover_a_reversal_waits_at_neutral_then_goes_through() -> None:
    guard = _settled_guard()
    t = SETTLE_S + 0.1
    assert guard.limit(t, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=True) == (0.0, 0.0, 0.5, 0.5)
    assert guard.held == 1
    t = SETTLE_S + MIN_INTERVAL_S + 0.01
    assert guard.limit(t, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=True) == (-0.3, 0.3, 0.5, 0.5)


def test_a_command_a_moving_body_or_a_fresh_hover_gets_full_authority() -> None:
    t = SETTLE_S + 0.1
    assert _settled_guard().limit(t, (-0.3, 0.3, 0.5, 0.5), hovering=False, calm=True) == (-0.3, 0.3, 0.5, 0.5)
    assert _settled_guard().limit(t, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=False) == (-0.3, 0.3, 0.5, 0.5)
    fresh = _settled_guard()
    fresh.limit(t, (0.3, -0.3, 0.5, 0.5), hovering=False, calm=True)  # a command: the hover restarts
    assert fresh.limit(t + 0.1, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=True) == (-0.3, 0.3, 0.5, 0.5)


def test_any_command_but_neutral_takes_a_direction() -> None:
    """The real deadband is unknown: a command inside the config's may spin the motor, so it counts."""
    guard = _settled_guard()
    t = SETTLE_S + 0.1
    assert guard.limit(t, (-0.05, -0.04, 0.5, 0.5), hovering=True, calm=True) == (0.0, -0.04, 0.5, 0.5)
    assert guard.limit(t + 0.02, (0.0, 0.0, 0.5, 0.5), hovering=True, calm=True) == (0.0, 0.0, 0.5, 0.5)
    assert guard.held == 1


def test_a_still_body_turning_keeps_a_motor_from_reversing_alone_but_lets_the_torque_turn() -> None:
    """Still (under CALM_SPEED_M_S) but turning faster than calm: one motor reversing alone is a surge
    push against the motor holding the yaw torque, and waits (the partner keeps the torque); both
    reversing is the torque turning, and goes through (corner-mTDL: the surge push saturated against the
    motor holding the torque at 2.5-4 deg/s, that motor reversed at each engagement and back)."""
    guard = ReversalGuard(PAIR)
    guard.limit(0.0, (0.3, -0.3, 0.5, 0.5), hovering=True, calm=False, still=True)
    assert guard.limit(SETTLE_S, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=False, still=True) == (-0.3, 0.3, 0.5, 0.5)
    t = SETTLE_S + 0.1
    out = guard.limit(t, (-0.6, -0.2, 0.5, 0.5), hovering=True, calm=False, still=True)
    assert out[1] == 0.0 and out[0] < 0.0
    assert _torque(out) == pytest.approx(_torque((-0.6, -0.2)), rel=1e-9)
    assert guard.limit(t + 0.02, (0.3, -0.3, 0.5, 0.5), hovering=True, calm=False, still=True) == (0.3, -0.3, 0.5, 0.5)
    # Moving (not still), or not yet settled in the hover: full authority.
    moving = ReversalGuard(PAIR)
    moving.limit(0.0, (0.3, -0.3, 0.5, 0.5), hovering=True, calm=False, still=False)
    moving.limit(SETTLE_S, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=False, still=False)
    assert moving.limit(t, (-0.6, -0.2, 0.5, 0.5), hovering=True, calm=False, still=False) == (-0.6, -0.2, 0.5, 0.5)
    fresh = ReversalGuard(PAIR)
    fresh.limit(0.0, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=False, still=True)
    assert fresh.limit(0.1, (-0.6, -0.2, 0.5, 0.5), hovering=True, calm=False, still=True) == (-0.6, -0.2, 0.5, 0.5)


def test_calm_is_inside_the_stop_goal() -> None:
    assert calm(0.0, 0.0)
    assert not calm(CALM_SPEED_M_S, 0.0) and not calm(0.0, -CALM_YAW_DPS)
    assert CALM_SPEED_M_S < 0.05 and CALM_YAW_DPS < 3.0  # the stop goal's thresholds


@settings(deadline=None, max_examples=50)
@given(seed=st.integers(0, 2**31 - 1))
def test_in_calm_hover_no_motor_reverses_more_often_than_the_interval_allows(seed: int) -> None:
    rng = np.random.default_rng(seed)
    guard = ReversalGuard()
    last_sign, last_t = [0.0, 0.0], [-np.inf, -np.inf]
    for k in range(2000):
        t = 0.02 * k
        wanted = tuple(float(x) for x in rng.uniform(-0.5, 0.5, 2))
        out = guard.limit(t, (wanted[0], wanted[1], 0.5, 0.5), hovering=True, calm=True)
        for i in range(2):
            if out[i] != 0.0:
                sign = float(np.sign(out[i]))
                if last_sign[i] and sign != last_sign[i] and t >= SETTLE_S:
                    assert t - last_t[i] >= MIN_INTERVAL_S - 1e-9
                if sign != last_sign[i]:
                    last_sign[i], last_t[i] = sign, t


PAIR = PairThrust(max_thrust_n=0.25, reverse_ratio=0.95, deadband=0.06)


def _torque(commands: tuple[float, ...]) -> float:
    """The pair's yaw torque per arm: left force minus right force (N)."""
    return PAIR.force(commands[0]) - PAIR.force(commands[1])


def test_a_held_motor_s_partner_keeps_the_pair_s_yaw_torque_and_gives_up_the_surge() -> None:
    """Holding one motor alone turns a surge correction into a yaw kick: the partner is rebalanced."""
    guard = ReversalGuard(PAIR)
    guard.limit(0.0, (-0.3, 0.3, 0.5, 0.5), hovering=True, calm=True)
    guard.limit(SETTLE_S, (0.3, -0.3, 0.5, 0.5), hovering=True, calm=True)  # the directions taken at SETTLE_S
    wanted = (0.45, 0.2, 0.5, 0.5)  # a surge push on top of the yaw torque: the right motor would reverse
    out = guard.limit(SETTLE_S + 0.1, wanted, hovering=True, calm=True)
    assert out[1] == 0.0 and 0.0 < out[0] < wanted[0]
    assert _torque(out) == pytest.approx(_torque(wanted), rel=1e-9)
    assert PAIR.force(out[0]) + PAIR.force(out[1]) < PAIR.force(wanted[0]) + PAIR.force(wanted[1])
    # Keeping the torque would reverse the partner too: both wait at neutral.
    assert guard.limit(SETTLE_S + 0.12, (0.2, 0.45, 0.5, 0.5), hovering=True, calm=True) == (0.0, 0.0, 0.5, 0.5)


@settings(deadline=None, max_examples=50)
@given(seed=st.integers(0, 2**31 - 1))
def test_the_guard_never_turns_the_pair_s_torque_the_other_way_nor_makes_it_larger(seed: int) -> None:
    rng = np.random.default_rng(seed)
    guard = ReversalGuard(PAIR)
    for k in range(1000):
        wanted = (float(rng.uniform(-0.6, 0.6)), float(rng.uniform(-0.6, 0.6)), 0.5, 0.5)
        out = guard.limit(0.02 * k, wanted, hovering=True, calm=True)
        torque, asked = _torque(out), _torque(wanted)
        assert torque * asked >= -1e-12
        assert abs(torque) <= abs(asked) + 1e-9
