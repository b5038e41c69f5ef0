"""Rate-command onsets: minimum-time (the actuators' full acceleration through the motor lag) and quiet.

Unit and property tests of the onset reference and of the physical latency
floor, then the controller flying the simulator: each command's latency
against the floor the physics allows, how far the body may exceed the
commanded rate, switching straight from one command to its opposite, the
100 ms target for every command with the spec propellers (reversible 3D on
the horizontal pair), and the one-direction what-if behind that spec.
"""

from __future__ import annotations

from dataclasses import replace

import math
from functools import lru_cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.daemon.config import Config
from feelium.lab.flight import scenarios as sc
from feelium.flight.blimp_model import BlimpParams
from feelium.flight.controller import FlightController
from feelium.flight.config import FlightConfig
from feelium.flight.references import HANDOVER_S, RateOnset as _RateOnset
from feelium.lab.flight.latency_floor import available_accel, lag_response_time, latency_floor, one_direction_horizontal_propellers
from feelium.flight.setpoint import setpoint_for_motion

THRUST_LAG_S = FlightConfig().motor_lag_s
# The tight goals are for a fitted model (what `feelium calibrate flight` writes): the plant is the config.
CONFIG = replace(Config().flight, plant_uncertainty=1.0)
COMMANDS = ("forward", "backward", "up", "down", "turn_left", "turn_right")


# ------------------------------------------------------------------ the onset reference
def test_onset_asks_for_the_full_acceleration_first() -> None:
    onset = _RateOnset(THRUST_LAG_S)
    onset.start(0.0, 0.0)
    rate, predicted, command = onset.step(0.25, (-0.75, 1.4), 0.02)
    assert (rate, predicted, command) == (0.0, 0.0, 1.4)
    _, _, command = onset.step(-0.25, (-0.75, 1.4), 0.02)  # reversed: the other limit
    assert command == -0.75


def test_onset_hands_over_smoothly_and_settles_on_the_commanded_rate() -> None:
    onset = _RateOnset(THRUST_LAG_S)
    onset.start(0.0, 0.0)
    commands = [onset.step(0.15, (-0.4, 0.68), 0.02)[2] for _ in range(150)]
    assert commands[0] == 0.68
    tail = commands[commands.index(next(c for c in commands if c < 0.68)) :]
    assert all(b <= a + 1e-12 for a, b in zip(tail, tail[1:]))  # tapers monotonically, never bangs back
    assert math.isclose(onset.rate, 0.15, rel_tol=1e-3) and abs(onset.accel) < 1e-3


@settings(max_examples=300, deadline=None)
@given(
    target=st.floats(-2.0, 2.0),
    rate=st.floats(-2.0, 2.0),
    accel=st.floats(-3.0, 3.0),
    lo=st.floats(-3.0, 0.0),
    hi=st.floats(0.0, 3.0),
    dt=st.floats(0.005, 0.05),
)
def test_onset_predicted_rate_never_passes_the_commanded_rate(
    target: float, rate: float, accel: float, lo: float, hi: float, dt: float
) -> None:
    onset = _RateOnset(THRUST_LAG_S)
    onset.start(rate, accel)
    side = math.copysign(1.0, target - onset.predicted)
    for _ in range(100):
        _, predicted, command = onset.step(target, (lo, hi), dt)
        assert lo - 1e-12 <= command <= hi + 1e-12
        assert (target - predicted) * side >= -1e-9
    assert (target - onset.predicted) * side >= -1e-9


@settings(max_examples=300, deadline=None)
@given(target=st.floats(-2.0, 2.0), lo=st.floats(-3.0, -0.05), hi=st.floats(0.05, 3.0), dt=st.floats(0.005, 0.05))
def test_onset_from_rest_never_overshoots_and_arrives(target: float, lo: float, hi: float, dt: float) -> None:
    onset = _RateOnset(THRUST_LAG_S)
    onset.start(0.0, 0.0)
    limit = hi if target > 0 else -lo
    steps = int((abs(target) / limit + 12 * HANDOVER_S + 12 * THRUST_LAG_S) / dt) + 1
    for _ in range(steps):
        rate, _, _ = onset.step(target, (lo, hi), dt)
        assert abs(rate) <= abs(target) + 1e-9 and rate * target >= -1e-12
    assert abs(onset.rate - target) <= 1e-3 * max(abs(target), 1.0)


def test_a_brake_without_handover_lands_its_predicted_rate_on_zero_and_its_rate_follows_through_the_lag() -> None:
    """The turn brake's reference (``handover_s=0``): full deceleration until the rate predicted over the lag lands on
    zero within a cycle, then the rate itself tapers through that lag alone, never passing zero."""
    lag = 2.0 * THRUST_LAG_S
    brake = _RateOnset(lag, handover_s=0.0)
    brake.start(20.0, 0.0)
    steps = [brake.step(0.0, (-60.0, 60.0), 0.02) for _ in range(100)]
    commands = [command for _, _, command in steps]
    landed = next(i for i, (_, predicted, _) in enumerate(steps) if abs(predicted) < 1e-9)
    assert all(c == -60.0 for c in commands[: landed - 1])  # no taper before landing
    assert all(abs(c) < 1e-9 for c in commands[landed:])  # nothing commanded after it
    rates = [rate for rate, _, _ in steps]
    assert all(0.0 <= b <= a for a, b in zip(rates, rates[1:]))  # the rate falls through the lag, never below zero
    assert rates[landed] > 5.0 and rates[-1] < 0.01  # landing leaves the lag's share of the rate, which then decays


# ------------------------------------------------------------------ the mixer's limits and the physical floor
def test_mixer_limits_are_what_split_delivers() -> None:
    mixer = FlightController(CONFIG).mixer
    lo, hi = mixer.limits_surge_n()
    assert math.isclose(sum(mixer.split(10.0, 0.0, 0.0)[:2]), hi)
    assert math.isclose(sum(mixer.split(-10.0, 0.0, 0.0)[:2]), lo)
    assert math.isclose(-lo / hi, CONFIG.horizontal_reverse_ratio)
    down, up = mixer.limits_up_n()
    assert math.isclose(up / -down, CONFIG.vertical_reverse_ratio)
    assert math.isclose(sum(mixer.split(0.0, 10.0, 0.0)[2:]), -up)  # the vertical pair's full reverse (up) thrust
    left, right, _, _ = mixer.split(0.0, 0.0, 10.0)
    assert math.isclose((left - right) * CONFIG.arm_m, mixer.limit_yaw_nm())


@settings(max_examples=100, deadline=None)
@given(accel=st.floats(0.05, 5.0), threshold=st.floats(0.001, 0.5), tau=st.floats(0.0, 0.3))
def test_lag_response_time_solves_the_closed_form(accel: float, threshold: float, tau: float) -> None:
    t = lag_response_time(accel, threshold, tau)
    speed = accel * (t - tau * (1.0 - math.exp(-t / tau))) if tau > 0 else accel * t
    assert math.isclose(speed, threshold, rel_tol=1e-6)
    assert t >= threshold / accel * (1 - 1e-6)  # the lag only ever delays


def test_one_direction_horizontal_propellers_cannot_reach_100_ms_backward() -> None:
    """The physics the hardware spec rests on (docs/flight.md): with 60 % reverse thrust on the
    horizontal pair the floor itself is above the target; the spec's 3D propellers bring it under."""
    old_config, old_blimp = one_direction_horizontal_propellers(CONFIG)
    floor = latency_floor("backward", old_config, old_blimp)
    assert floor.closed_form_s > 0.100 and floor.slew_limited_s > 0.100
    assert latency_floor("backward", CONFIG).slew_limited_s < 0.100
    forward = available_accel("forward", CONFIG, BlimpParams())
    assert available_accel("backward", CONFIG, BlimpParams()) == pytest.approx(forward * CONFIG.horizontal_reverse_ratio)
    assert available_accel("backward", old_config, old_blimp) == pytest.approx(forward * 0.6)
    assert old_blimp.vertical_motor == BlimpParams().vertical_motor  # the what-if changes the horizontal pair only


@pytest.mark.parametrize("name", COMMANDS)
def test_the_spec_propellers_allow_100_ms_for_every_command(name: str) -> None:
    assert latency_floor(name, CONFIG).slew_limited_s < 0.100


# ------------------------------------------------------------------ the controller on the simulator
@lru_cache(maxsize=None)
def _motion(name: str, seed: int, one_direction: bool = False) -> sc.MotionResult:
    if one_direction:
        config, blimp = one_direction_horizontal_propellers(CONFIG)
        return sc.motion(config, name, hold_s=1.5, seed=seed, blimp=blimp)
    return sc.motion(CONFIG, name, hold_s=1.5, seed=seed)


@pytest.mark.slow
@pytest.mark.parametrize("name", COMMANDS)
def test_latency_is_at_the_physical_floor(name: str) -> None:
    result = _motion(name, 1)
    floor = latency_floor(name, CONFIG)
    # Within 5 ms of the best the mixer and slew limits allow from rest. The floor is from rest, so the
    # body's motion is measured as its change since the command: the hover leaves it drifting a few mm/s
    # either way, and that drift, not the controller, moved the raw latency by 10-15 ms (session 15: with
    # the simulator's sensor grid fixed, seed 1's `down` started at -0.5 cm/s, 85 ms raw against a floor of
    # 72 ms; seed 2 under the old grid started at +0.6 cm/s and read 56 ms, 16 ms *under* the floor).
    assert _latency_of_change(result, name) <= floor.slew_limited_s + 0.005


def _latency_of_change(result: sc.MotionResult, name: str) -> float:
    """Issue -> the body's rate has changed by the motion threshold the commanded way (interpolated)."""
    signal = result.fraction * result.commanded
    issued = int(np.nonzero(result.t >= -1e-9)[0][0])
    return sc._first_crossing(result.t, signal - signal[issued], sc.MOTION_THRESHOLD[name], 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("name", COMMANDS)
def test_every_command_moves_the_body_within_100_ms(name: str) -> None:
    """The issue's command-to-motion target, with the default (spec) hardware, over three seeds."""
    for seed in (1, 2, 3):
        assert _motion(name, seed).latency_s <= 0.100, seed


@pytest.mark.slow
@pytest.mark.parametrize("name", COMMANDS)
def test_onset_drives_the_motors_as_fast_as_the_slew_limit_allows(name: str) -> None:
    flight = sc.new_flight(CONFIG, drafts=False)
    flight.run(sc.SETTLE_S)
    before = flight.last.commands if flight.last else (0.0,) * 4
    after = [flight.step(setpoint_for_motion(name, CONFIG)).commands for _ in range(2)]
    driven = {"forward": (0, 1), "backward": (0, 1), "turn_left": (0, 1), "turn_right": (0, 1), "up": (2, 3), "down": (2, 3)}[name]
    step = CONFIG.slew_per_s / CONFIG.rate_hz
    for motor in driven:
        sequence = [before[motor]] + [c[motor] for c in after]
        for a, b in zip(sequence, sequence[1:]):
            # each cycle either a full slew step or already at full output
            assert abs(b - a) >= step - 1e-9 or abs(b) >= CONFIG.max_output - 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("name", COMMANDS)
def test_no_overshoot_of_the_commanded_rate_and_no_buzzing(name: str) -> None:
    for seed in (1, 2, 3):
        result = _motion(name, seed)
        assert result.peak_fraction <= 1.025, (seed, result.peak_fraction)  # the untouched step reached 1.029
        assert result.roughness < 1.0, (seed, result.roughness)  # a buzzing motor scores tens
        assert result.stop_s <= 0.5


@pytest.mark.slow
@pytest.mark.parametrize("first,second,key", [("forward", "backward", "u"), ("turn_right", "turn_left", "r_dps"), ("up", "down", "w")])
def test_switching_straight_to_the_opposite_command(first: str, second: str, key: str) -> None:
    flight = sc.new_flight(CONFIG, drafts=False)
    flight.run(sc.SETTLE_S)
    flight.run(2.0, setpoint_for_motion(first, CONFIG))
    start, t0 = len(flight.log["t"]), flight.t
    flight.run(2.0, setpoint_for_motion(second, CONFIG))
    t = flight.log["t"][start:] - t0
    motion = -flight.log[key][start:]  # the second command's direction
    cruise = {"u": CONFIG.forward_speed_m_s, "w": CONFIG.climb_rate_m_s, "r_dps": CONFIG.yaw_rate_dps}[key]
    assert motion.max() <= 1.02 * cruise  # no overshoot from the reversal
    assert motion[t <= 1.5][-1] >= 0.95 * cruise  # at the new rate within 1.5 s
    assert np.all(np.isfinite(motion))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["backward", "turn_left", "turn_right"])
def test_one_direction_horizontal_propellers_are_slower(name: str) -> None:
    """The what-if the spec rules out, flown: every command that needs reverse horizontal thrust
    gets going later; backward misses 100 ms. Commands that do not need it are unchanged."""
    spec, old = _motion(name, 1), _motion(name, 1, one_direction=True)
    assert old.latency_s > spec.latency_s + 0.005
    if name == "backward":
        assert old.latency_s > 0.100 >= spec.latency_s
        assert old.latency_s > spec.latency_s + 0.020


@pytest.mark.slow
def test_one_direction_horizontal_propellers_leave_forward_unchanged() -> None:
    assert _motion("forward", 1, one_direction=True).latency_s == pytest.approx(_motion("forward", 1).latency_s, abs=0.002)
