"""A held command on a fitted model closes its steady speed error on the flow (``SurgeLoop``'s cruise integral)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from feelium.daemon.config import Config
from feelium.flight import loops
from feelium.lab.flight import scenarios as sc
from feelium.flight.setpoint import setpoint_for_motion

SHIPPED = Config().flight
FITTED = replace(SHIPPED, surge_uncertainty=1.14)  # a calibration's surge box: the model trusted 0.37 s


def _cruise(config, seed: int) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """The mean speed over the last 2 s of a 5 s held ``forward`` and the peak, as fractions of the command."""
    result = sc.motion(config, "forward", hold_s=5.0, seed=seed)
    window = (result.t >= result.expired_s - 2.5) & (result.t <= result.expired_s - 0.5)
    return float(np.mean(result.fraction[window])), result.peak_fraction


def test_on_a_fitted_model_the_integral_brings_the_cruise_closer_to_the_command_without_overshoot(monkeypatch: pytest.MonkeyPatch) -> None:
    """Calibrated corner-mtDL at seed 1 cruised at 0.889 of the command (a miss of point 2's 10 %): the push was divided
    by an onset's confirmed effectiveness, 1.37, and the proportional loop left the rest as a steady error. The
    integral follows the flow, so a seed whose flow noise reads low cruises a little over (seed 2: 1.013); on average
    the cruise is closer to the command, and no seed is more than 4 % off (seed 1: 0.966, 0.958 without)."""
    with_integral = [_cruise(FITTED, seed) for seed in range(1, 7)]
    monkeypatch.setattr(loops, "CRUISE_INTEGRAL_GAIN", 0.0)
    without = [_cruise(FITTED, seed) for seed in range(1, 7)]
    error = np.mean([abs(cruise - 1.0) for cruise, _ in with_integral])
    plain_error = np.mean([abs(cruise - 1.0) for cruise, _ in without])
    assert error < plain_error - 0.004
    assert all(abs(cruise - 1.0) <= 0.04 for cruise, _ in with_integral)
    assert max(peak for _, peak in with_integral) <= max(peak for _, peak in without) + 0.01  # no overshoot bought


def test_the_shipped_box_and_a_released_command_have_no_integral() -> None:
    """The shipped config (no fit) flies as before, bit for bit; a brake owes the cruise nothing."""
    for config, seed in ((SHIPPED, 1), (FITTED, 1)):
        flight = sc.new_flight(config, False, seed)
        flight.run(sc.SETTLE_S)
        loop = flight.controller.surge_loop  # type: ignore[attr-defined]
        integrals = []
        for _ in range(int(4.0 * config.rate_hz)):
            flight.step(setpoint_for_motion("forward", config))
            integrals.append(loop.cruise_integral)
        assert (max(np.abs(integrals)) == 0.0) == (config is SHIPPED)
        flight.step()
        assert loop.cruise_integral == 0.0


def test_a_command_reversed_mid_way_starts_without_the_push_the_other_way_learned() -> None:
    """The integral belongs to one setpoint: a ``forward`` turned straight into ``backward`` (the headset sends one
    after the other) must not carry 0.1 m/s^2 of forward push into the reversal."""
    flight = sc.new_flight(FITTED, False, 1)
    flight.run(sc.SETTLE_S)
    loop = flight.controller.surge_loop  # type: ignore[attr-defined]
    for _ in range(int(4.0 * FITTED.rate_hz)):
        flight.step(setpoint_for_motion("forward", FITTED))
    assert loop.cruise_integral != 0.0
    flight.step(setpoint_for_motion("backward", FITTED))
    assert loop.cruise_integral == 0.0
