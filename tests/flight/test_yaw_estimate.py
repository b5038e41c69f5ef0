"""The fine heading: the gyro carries the heading between the board's whole degrees, the board keeps it honest."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.daemon.config import Config
from feelium.flight.estimators import YawEstimate

DT = 0.02


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


@settings(deadline=None, max_examples=30)
@given(rate_dps=st.floats(-6.0, 6.0), start=st.floats(0.0, 360.0), bias_dps=st.floats(-0.2, 0.2), seed=st.integers(0, 2**16))
def test_the_fine_heading_moves_smoothly_and_stays_within_the_board_s_rounding(rate_dps: float, start: float, bias_dps: float,
                                                                              seed: int) -> None:
    """A body turning slowly (as in hover): the board steps by whole degrees, the fine heading by no more than
    the turn, and it stays within the board's half degree of rounding (plus a little gyro noise and bias)."""
    rng = np.random.default_rng(seed)
    est = YawEstimate(Config().flight)
    true = start
    previous = None
    for k in range(400):
        true = (true + rate_dps * DT) % 360.0
        gyro = rate_dps + bias_dps + 0.3 * float(rng.standard_normal())
        est.update(k * DT, DT, float(round(true) % 360), gyro, 0.0)
        fine = est.fine_heading
        assert fine is not None
        if previous is not None:
            assert abs(_wrap(fine - previous)) <= (abs(rate_dps) + 2.0) * DT  # no whole-degree steps
        previous = fine
        if k * DT >= 3.0:
            assert abs(_wrap(fine - true)) <= 0.8  # 0.5 of rounding, 0.2 of bias over the 1 s pull, noise


@settings(deadline=None, max_examples=20)
@given(rate_dps=st.floats(30.0, 40.0), sign=st.sampled_from([-1.0, 1.0]), drag_error=st.floats(0.5, 2.0))
def test_a_held_turn_against_the_air_teaches_no_weak_yaw(rate_dps: float, sign: float, drag_error: float) -> None:
    """A steady turn's torque balances the air's drag and changes no rate. The least drag the box allows is added back
    to the measured rate (as the surge adds its model's), so that push is not read as a push that moved nothing:
    unlearned, it taught the side the box's weakest and the next hover correction pushed nine times too hard (session
    37). With the real drag ``drag_error`` times the config's (and the config's inertia and thrust), a held turn reads
    the least drag's share of the truth: never more than the truth (the config's drag added back read a low-drag plant
    twice too strong), never the floor."""
    config = Config().flight
    est = YawEstimate(config)
    rate = np.radians(sign * rate_dps)
    torque = drag_error * config.yaw_drag * rate * abs(rate)  # what holds the real body's rate
    for k in range(500):
        est.update(k * DT, DT, None, float(np.degrees(rate)), torque)
    assert est.effectiveness.is_taught(sign)
    least_share = 1.0 / config.uncertainty("yaw") / drag_error
    assert est.effectiveness.value(sign) == pytest.approx(least_share, rel=0.05)
    assert est.effectiveness.value(sign) <= 1.0 + 1e-9


def _turn(est: YawEstimate, t: float, rate: float, seconds: float, torque: float, gain: float) -> tuple[float, float]:
    """Push with ``torque`` for ``seconds`` on a body answering ``gain`` times the config's model (no drag)."""
    config = est.c
    for _ in range(round(seconds / DT)):
        t += DT
        rate += gain * torque / config.yaw_inertia_kg_m2 * DT
        est.update(t, DT, None, float(np.degrees(rate)), torque)
    return t, rate


def test_the_yaw_limits_a_falling_value_and_learns_nothing_from_windows_that_change_sign() -> None:
    """The yaw takes ``Effectiveness(halving_falls=True, one_way=True)``: a window the body seemed not to answer lowers
    a taught side by at most half (one such window took corner-mTdl's from 1.52 to 0.19, session 37), and a window
    mixing a turn's last pushes with its brake's first teaches nothing (one confirmed a brake side at 3.12)."""
    est = YawEstimate(Config().flight)
    t, rate = _turn(est, 0.0, 0.0, 1.0, 0.004, 1.0)
    taught = est.effectiveness.value(1.0)
    assert taught == pytest.approx(1.0, rel=0.1)
    t, rate = _turn(est, t, rate, 0.3, 0.03, 0.05)  # a push the rate barely answered: read as weak
    assert est.effectiveness.value(1.0) >= 0.5 * taught - 1e-9
    def alternate(t: float, rate: float, seconds: float) -> tuple[float, float]:
        """Two cycles one way, one the other: a net push well over the windows' least, 71 % of their pushes' sum."""
        for _ in range(round(seconds / (3 * DT))):
            t, rate = _turn(est, t, rate, 2 * DT, 0.03, 1.0)
            t, rate = _turn(est, t, rate, DT, -0.03, 1.0)
        return t, rate

    t, rate = alternate(t, rate, 0.45)  # until the windows hold nothing of the one-way pushes before
    mixed, samples = est.effectiveness.mixed_windows, list(est.effectiveness.samples)
    alternate(t, rate, 0.6)
    assert est.effectiveness.mixed_windows > mixed
    assert est.effectiveness.samples == samples
