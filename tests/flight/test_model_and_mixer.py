"""Blimp physics and the mixer: buoyancy, drag, motor curve, and the mixer's inverse of it."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from feelium.flight import blimp_model as bm
from feelium.flight.mixer import Mixer, MixerGeometry, command_for_thrust, thrust_for_command, to_microseconds


def test_paper_body_is_positively_buoyant_by_36_grams() -> None:
    params = bm.BlimpParams()
    assert math.isclose(params.net_buoyancy_n, (0.360 - 0.3237) * 9.81, rel_tol=1e-9)
    assert params.inertial_mass_kg > params.rigid_mass_kg > params.body_mass_kg


def test_motors_off_it_rises_to_a_terminal_speed_then_the_ceiling() -> None:
    params = bm.BlimpParams(ceiling_m=100.0)
    state = bm.BlimpState(z=1.0)
    for _ in range(4000):  # 20 s
        state = bm.step(params, state, (0.0, 0.0, 0.0, 0.0), 0.005)
    k1, k2 = params.linear_drag_n_per_m_s, params.quadratic_drag
    terminal = (-k1 + math.sqrt(k1 * k1 + 4 * k2 * params.net_buoyancy_n)) / (2 * k2)
    assert math.isclose(state.w, terminal, rel_tol=0.02)
    capped = bm.BlimpState(z=2.99, w=1.0)
    assert bm.step(bm.BlimpParams(), capped, (0.0,) * 4, 0.05).z == 3.0  # type: ignore[arg-type]


def test_vertical_motors_hold_it_down_and_thrust_lags() -> None:
    params = bm.BlimpParams()
    motor = params.vertical_motor
    hold_command = command_for_thrust(params.net_buoyancy_n / 2, motor.max_thrust_n, motor.reverse_ratio, motor.deadband)
    state = bm.BlimpState(z=1.0)
    first = bm.step(params, state, (0.0, 0.0, hold_command, hold_command), 0.005)
    assert 0.0 < first.thrust_n[2] < params.net_buoyancy_n / 2 * 0.2  # the lag: a fraction after 5 ms
    for _ in range(400):
        state = bm.step(params, state, (0.0, 0.0, hold_command, hold_command), 0.005)
    assert math.isclose(state.thrust_n[2] + state.thrust_n[3], params.net_buoyancy_n, rel_tol=1e-3)
    later = state
    for _ in range(400):
        later = bm.step(params, later, (0.0, 0.0, hold_command, hold_command), 0.005)
    assert 0.0 <= later.w < state.w  # only the rise begun during the lag remains, and drag slows it


def test_differential_thrust_turns_clockwise_when_left_pushes_harder() -> None:
    state = bm.BlimpState()
    for _ in range(200):
        state = bm.step(bm.BlimpParams(), state, (0.6, -0.6, 0.0, 0.0), 0.005)
    assert state.r > 0


def test_deadband_makes_no_thrust() -> None:
    motor = bm.MotorParams(max_thrust_n=0.3, reverse_ratio=0.6, deadband=0.06)
    assert motor.static_thrust(0.05) == 0.0 and motor.static_thrust(-0.05) == 0.0
    assert motor.static_thrust(1.0) == 0.3 and math.isclose(motor.static_thrust(-1.0), -0.3 * motor.reverse_ratio)


@given(force=st.floats(-0.15, 0.25))
def test_mixer_inverts_the_thrust_curve(force: float) -> None:
    command = command_for_thrust(force, 0.25, 0.6, 0.06)
    assert -1.0 <= command <= 1.0
    if abs(force) > 0.01 * 0.25:  # past the deadband blend the force is reproduced
        assert math.isclose(thrust_for_command(command, 0.25, 0.6, 0.06), force, rel_tol=1e-6, abs_tol=1e-9)


@given(surge=st.floats(-2, 2), up=st.floats(-2, 2), yaw=st.floats(-1, 1), previous=st.floats(-1, 1))
def test_mixer_outputs_respect_limits_and_slew(surge: float, up: float, yaw: float, previous: float) -> None:
    mixer = Mixer(_geometry(max_output=0.9, slew_per_s=5.0))
    mixer.reset((previous * 0.9,) * 4)  # type: ignore[arg-type]
    out = mixer.mix(surge, up, yaw, 0.02)
    for before, after in zip((previous * 0.9,) * 4, out):
        assert abs(after) <= 0.9 + 1e-12
        assert abs(after - before) <= 5.0 * 0.02 + 1e-12


def test_mixer_keeps_yaw_when_surge_saturates() -> None:
    mixer = Mixer(_geometry(max_output=1.0, slew_per_s=100.0))
    left, right, _, _ = mixer.split(surge_n=10.0, up_n=0.0, yaw_nm=0.02)
    assert math.isclose((left - right) * 0.25, 0.02, rel_tol=1e-9)


def _geometry(max_output: float, slew_per_s: float) -> MixerGeometry:
    return MixerGeometry(
        arm_m=0.25, horizontal_thrust_n=0.25, vertical_thrust_n=0.5, horizontal_reverse_ratio=0.95, vertical_reverse_ratio=0.6,
        deadband=0.06, max_output=max_output, slew_per_s=slew_per_s,
    )


def test_each_motor_pair_reverses_with_its_own_propellers() -> None:
    """Horizontal pair: reversible 3D propellers (95 %); vertical pair: one-direction ones (60 %)."""
    mixer = Mixer(_geometry(max_output=1.0, slew_per_s=100.0))
    left, right, front, rear = mixer.split(surge_n=-10.0, up_n=10.0, yaw_nm=0.0)  # full reverse on all four
    assert math.isclose(left, -0.25 * 0.95) and math.isclose(right, -0.25 * 0.95)
    assert math.isclose(front, -0.5 * 0.6) and math.isclose(rear, -0.5 * 0.6)
    assert mixer.mix(-10.0, 10.0, 0.0, 1.0) == (-1.0, -1.0, -1.0, -1.0)  # each at full reverse command
    assert math.isclose(mixer.limit_yaw_nm(), 0.25 * (1.0 + 0.95) * 0.25)
    params = bm.BlimpParams()
    assert math.isclose(params.horizontal_motor.static_thrust(-1.0), -0.25 * 0.95)
    assert math.isclose(params.vertical_motor.static_thrust(-1.0), -0.5 * 0.6)


def test_controller_defaults_match_the_simulated_propellers() -> None:
    """The controller's knowledge of the propellers ([flight]) and the simulated body agree by default."""
    from feelium.flight.config import FlightConfig

    config, params = FlightConfig(), bm.BlimpParams()
    assert config.horizontal_reverse_ratio == params.horizontal_motor.reverse_ratio == 0.95
    assert config.vertical_reverse_ratio == params.vertical_motor.reverse_ratio == 0.6


def test_microseconds_centre_on_neutral() -> None:
    assert to_microseconds((0.0, 1.0, -1.0, 0.5)) == (1500, 2000, 1000, 1750)
