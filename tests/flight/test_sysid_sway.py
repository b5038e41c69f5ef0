"""The surge fit's turn term: in a turning body frame the forward speed gains sway x yaw rate with no force.

One-motor yaw steps push the body forward while it turns; the turn swings that speed into sway and back.
These tests fly the model's physics (``blimp_model.step``, still air, exact readings) through such pushes and
check the surge fit on its own: with the sideways flow reading it recovers the thrust and drag per mass and a
turn coefficient of 1 (the simulator's rigid-body kinematics); without it, the same record misleads the fit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from feelium.flight import sysid
from feelium.flight.blimp_model import BlimpParams, BlimpState, step

PHYSICS_DT, TICK_S = 0.005, 0.02


def _one_motor_flight(seed: int, params: BlimpParams) -> sysid.FlightRecord:
    """Pushes of 1.5-3 s, one motor alone or both, forward or reverse, with rests; readings at each tick, the
    flow one physics step old (the age the fit assumes is 5 ms)."""
    rng = np.random.default_rng(seed)
    state, rows, t = BlimpState(z=1.5), [], 0.0
    previous = state
    for _ in range(24):
        level = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 0.7))
        left, right = [(level, 0.0), (0.0, level), (level, level)][int(rng.integers(3))]
        for commands, seconds in (((left, right, 0.0, 0.0), rng.uniform(1.5, 3.0)), ((0.0, 0.0, 0.0, 0.0), rng.uniform(1.0, 2.0))):
            for _ in range(int(seconds / TICK_S)):
                z = state.z
                rows.append((t, *commands, z, math.degrees(state.r), previous.u / z, previous.v / z))
                for _ in range(int(round(TICK_S / PHYSICS_DT))):
                    previous, state = state, step(params, state, commands, PHYSICS_DT)
                    state = BlimpState(state.x, state.y, 1.5, state.heading_rad, state.u, state.v, 0.0, state.r, state.thrust_n)
                t += TICK_S
    a = np.asarray(rows)
    return sysid.FlightRecord(t=a[:, 0], commands=a[:, 1:5], range_m=a[:, 5], yaw_rate_dps=a[:, 6],
                              flow_x_rad_s=a[:, 7], flow_y_rad_s=a[:, 8])


def _surge_errors(record: sysid.FlightRecord, params: BlimpParams) -> dict[str, float]:
    sig = sysid.prepare(record)
    motor = params.horizontal_motor
    fit = sysid.surge_fit(sig, motor.time_constant_s - PHYSICS_DT, motor.deadband)  # the simulator's effective lag
    mass = params.inertial_mass_kg * params.surge_mass_factor
    truth = {"thrust_per_mass": motor.max_thrust_n / mass, "quadratic_drag_per_mass": params.quadratic_drag / mass}
    errors = {name: fit.estimate(name).value / value - 1.0 for name, value in truth.items()}
    errors["sway_coupling"] = fit.estimate("sway_coupling").value - 1.0
    return errors


@pytest.mark.parametrize("seed", [1, 2])
def test_with_the_sideways_flow_the_surge_fit_recovers_a_turning_flight(seed: int) -> None:
    params = BlimpParams(sway_mass_factor=1.4)  # a sway mass unlike the surge's: the kinematic term is still 1
    errors = _surge_errors(_one_motor_flight(seed, params), params)
    assert abs(errors["thrust_per_mass"]) < 0.02 and abs(errors["quadratic_drag_per_mass"]) < 0.05, errors
    assert abs(errors["sway_coupling"]) < 0.03, errors


def test_without_the_sideways_flow_the_turns_mislead_the_surge_fit() -> None:
    """The same flight with the sway reading lost (zero): the fit has no turn term to explain the forward speed a
    turn swings away and back, and the drag per mass it returns is off by far more than with it."""
    params = BlimpParams()
    record = _one_motor_flight(1, params)
    blind = sysid.FlightRecord(record.t, record.commands, record.range_m, record.yaw_rate_dps, record.flow_x_rad_s,
                               np.zeros_like(record.flow_y_rad_s))
    with_sway, without = _surge_errors(record, params), _surge_errors(blind, params)
    assert abs(without["quadratic_drag_per_mass"]) > 5 * max(abs(with_sway["quadratic_drag_per_mass"]), 0.01), (with_sway, without)
