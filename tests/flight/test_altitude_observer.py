"""The altitude observer on a blimp nobody tuned it to: the range slope, the heave effectiveness, the limits.

The climb rate a loop damps must be measured, not predicted: these tests
check the rangefinder's own slope (exact on a ramp, bounded with noise,
silent with too few readings), that the heave effectiveness finds the true
ratio of a plant twice as heavy, and that the heavy, weak corner of the box
(motors that barely hold its buoyancy) stops a held climb at the ceiling.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.daemon.config import Config
from feelium.flight.controller import FlightController
from feelium.flight.estimators import (
    DISTURBANCE_SLEW_M_S3,
    RANGE_LATENCY_S,
    RANGE_RATE_WINDOW_S,
    AltitudeObserver,
    RangeRate,
    air_drag,
)
from feelium.flight.references import HANDOVER_S
from feelium.flight.setpoint import setpoint_for_motion
from feelium.flight.sim_board import BoardParams, board_with
from feelium.lab.flight.plants import corner_plants
from feelium.lab.flight.simulation import SimFlight


@given(rate=st.floats(-2.0, 2.0), start=st.floats(0.1, 3.0), t0=st.floats(0.0, 1e5))
def test_the_range_slope_of_a_ramp_is_its_rate(rate: float, start: float, t0: float) -> None:
    slope = RangeRate()
    for k in range(40):
        t = t0 + 0.02 * k
        slope.add(t, start + rate * (t - t0))
    measured = slope.rate(t0 + 0.02 * 39)
    assert measured is not None and measured == pytest.approx(rate, abs=1e-6)


@settings(deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_the_range_slope_with_sensor_noise_stays_within_a_few_cm_per_s(seed: int) -> None:
    rng = np.random.default_rng(seed)
    slope = RangeRate()
    errors = []
    for k in range(500):
        t = 0.02 * k
        slope.add(t, 1.2 + 0.1 * t + 0.01 * float(rng.standard_normal()))  # 1 cm noise, the sim's VL53L1X at 1.2 m
        measured = slope.rate(t)
        if measured is not None:
            errors.append(measured - 0.1)
    # The least-squares slope of 15 readings over 0.3 s: about 3 cm/s of noise.
    assert np.std(errors) < 0.05 and abs(np.mean(errors)) < 0.01


def test_the_range_slope_says_nothing_without_enough_readings_and_tells_its_age() -> None:
    slope = RangeRate()
    for k in range(4):
        slope.add(0.02 * k, 1.0)
    assert slope.rate(0.06) is None
    slope.add(0.08, 1.0)
    slope.add(0.10, 1.0)
    assert slope.rate(0.10) == pytest.approx(0.0)
    assert slope.rate(10.0) is None  # a gap longer than the window: every reading has aged out
    assert slope.age_s == pytest.approx(0.5 * RANGE_RATE_WINDOW_S + RANGE_LATENCY_S)


def _corner(label: str):
    return next(plant for plant in corner_plants() if plant.name == f"corner-{label}")


def _climbs_and_descents(flight: SimFlight, config, cycles: int) -> None:
    for _ in range(cycles):
        for name, seconds in (("up", 2.0), (None, 3.0), ("down", 2.0), (None, 3.0)):
            flight.run(seconds, setpoint_for_motion(name, config))


def test_the_heave_effectiveness_finds_a_blimp_twice_as_heavy() -> None:
    config = Config().flight
    nominal = BoardParams().blimp
    heavy = replace(nominal, heave_mass_factor=2.0 * nominal.heave_mass_factor)
    flight = SimFlight(config, board_with(BoardParams(blimp=heavy), z=1.2))
    flight.run(6.0)
    _climbs_and_descents(flight, config, 3)
    learned = flight.controller.altitude.effectiveness
    assert min(learned.samples) > 0
    # The model's heave mass is the nominal one: this body answers each push about half as much.
    # (It starts at 4, the strongest plant of the box, and may settle anywhere in 0.25..4 if it learns nothing.)
    for value in learned.values:
        assert 0.35 < value < 0.75, learned.as_dict()


@pytest.mark.parametrize("label", ["Mtdl", "MtDL"])
def test_a_heavy_blimp_whose_motors_barely_hold_it_down_stops_a_held_climb_at_the_ceiling(label: str) -> None:
    config = Config().flight
    flight = SimFlight(config, board_with(BoardParams(blimp=_corner(label).blimp), z=1.2))
    flight.run(8.0)
    flight.run(12.0, setpoint_for_motion("up", config))
    flight.run(4.0)
    z = flight.log["z"]
    assert z.max() <= config.altitude_max_m + 0.1
    assert abs(z[-1] - config.altitude_max_m) < 0.15  # and it holds near the limit, not somewhere below


def test_a_light_blimp_with_strong_motors_starts_without_falling_through_the_floor_limit() -> None:
    config = Config().flight
    flight = SimFlight(config, board_with(BoardParams(blimp=_corner("MTdl").blimp), z=1.2))
    flight.run(12.0)
    z = flight.log["z"]
    assert z.min() >= config.altitude_min_m - 0.1
    assert abs(z[-1] - 1.2) < 0.1


def _climb_rate_noise(config, climbing: bool, seed: int = 5) -> float:
    """The observer's climb-rate error (std, m/s) on a body climbing steadily at 0.25 m/s, the modelled force
    exactly the one that holds that climb, the rangefinder 1.6 cm noisy at 50 Hz (the sim's at 1.5 m)."""
    rng = np.random.default_rng(seed)
    observer = AltitudeObserver(config)
    observer.climbing = climbing
    rate, dt = 0.25, 0.02
    force = air_drag(rate, config.quadratic_drag) - config.net_buoyancy_n  # up force: buoyancy and drag balanced
    observer.update(0.0, 1.0, force, dt)
    observer.vz = rate
    errors = []
    for k in range(1, 1500):
        t = k * dt
        body = 1.0 + rate * (t - RANGE_LATENCY_S)
        observer.update(t, body + 0.016 * float(rng.standard_normal()), force, dt)
        if t > 5.0:
            errors.append(observer.vz - rate)
    return float(np.std(errors))


def test_in_a_held_climb_on_a_trusted_model_the_observer_passes_less_range_noise_to_the_climb_rate() -> None:
    """The held climb's rate loop damps the observer's climb rate alone: at the full 0.6 Hz the range noise moved
    it 2.5-3 cm/s for half a second and the body with it (test_onset's held `up`, seed 3: 1.030). On a trusted
    model a held climb follows the rangefinder at half the bandwidth; a doubted model keeps the full one."""
    trusted = replace(Config().flight, plant_uncertainty=1.0)
    held, climbing = _climb_rate_noise(trusted, False), _climb_rate_noise(trusted, True)
    assert climbing < 0.6 * held, (climbing, held)
    doubted = Config().flight
    assert _climb_rate_noise(doubted, True) == _climb_rate_noise(doubted, False)


def _heave_windows(observer: AltitudeObserver, seconds: float, push: Callable[[float], float], gain: float,
                   noise: float = 0.0, seed: int = 1) -> None:
    """Teach the observer's heave effectiveness: a body whose climb rate changes by ``gain`` x the modelled push,
    read through a range slope ``noise`` m/s noisy (the slope's noise over 0.3 s of a 1.6 cm sensor is 0.048)."""
    rng = np.random.default_rng(seed)
    rate, dt = 0.0, 0.02
    for k in range(int(seconds / dt)):
        observer.effectiveness.update(k * dt, dt, push(k * dt), rate + noise * float(rng.standard_normal()))
        rate += gain * push(k * dt) * dt


def test_a_few_heave_windows_barely_above_the_range_noise_do_not_teach_the_limit_margin() -> None:
    """Calibrated corner-MtdL at flight seed 3: three windows of its climb's onset, each changing the modelled climb
    rate by 0.031 m/s (the noise of one window's measured change is about 0.07) and measured at 2.5 times that,
    taught the down side's margin 2.54 (true about 1); the climb planned its braking on it and went 0.40 m through
    the ceiling limit. The loop's normalisation may learn from them; the margin counts on the box's weakest."""
    observer = AltitudeObserver(Config().flight)
    _heave_windows(observer, 0.56, lambda t: -0.062, gain=2.5)
    e = observer.effectiveness
    assert e.samples[0] == 3 and e.value(-1.0) == pytest.approx(2.5, rel=0.01)
    assert e.assured(-1.0) == e.lowest(-1.0)


def test_seconds_of_real_heave_pushes_of_differing_sizes_teach_the_limit_margin_most_of_what_they_measured() -> None:
    """Eight seconds of pushes on a body that answers them exactly, through a range slope as noisy as the sensor's, at
    40 seeds. The heave's answer is a line's slope (its offset takes the force the model misses), as certain as its
    pushes differ: pushes of +-0.5 m/s^2 alone teach a line whose slope the noise moves 0.73-1.19 about the true 1.0,
    and the margin stays at the box's weakest (through the origin it counted on about 0.6 before session 30, from a
    model the seed-70 corners showed four times off); pushes of 0.3 and 1.2 in turn teach the value within 0.1 and the
    margin the learned value two standard errors low, 0.51-0.67, never above it. Seeds 1-3 alone once hid the first
    spread (the session-30 review, finding 4; the session-31 review, finding 5, on which estimate it is)."""
    alike_values = []
    for seed in range(1, 41):
        alike = AltitudeObserver(Config().flight)
        _heave_windows(alike, 8.0, lambda t: 0.5 * math.sin(math.pi * t), gain=1.0, noise=0.048, seed=seed)
        differing = AltitudeObserver(Config().flight)
        _heave_windows(differing, 8.0, lambda t: (1.2 if int(t / 2.0) % 2 else 0.3) * math.sin(math.pi * t),
                       gain=1.0, noise=0.048, seed=seed)
        for push in (-1.0, 1.0):
            alike_values.append(alike.effectiveness.value(push))
            assert alike.effectiveness.value(push) == pytest.approx(1.0, abs=0.3)
            assert alike.effectiveness.assured(push) == alike.effectiveness.lowest(push)
            e = differing.effectiveness
            assert e.value(push) == pytest.approx(1.0, abs=0.1)
            assert 0.5 < e.assured(push) < e.value(push)
    assert float(np.median(alike_values)) == pytest.approx(1.0, abs=0.05)


@pytest.mark.parametrize("motion", ["up", None])
def test_in_a_held_climb_the_hold_force_learns_nothing_while_the_motors_catch_up_with_a_limit(motion: str | None) -> None:
    """The disturbance (the force a hold lacks) learns while the loop is in charge, but in a held climb not for the
    box's longest motor lag after a cycle at a motor limit: what the model misses then is its lag's error, not a
    force (calibrated corner-MtdL, flight seed 3: +0.3 m/s^2 learned on and off the down limit of a climb, truth
    about 0.01). A hold learns again at once: a heavy corner hovering near its motors' limit needs it."""
    config = Config().flight
    controller = FlightController(config)
    observer, loop = controller.altitude, controller.altitude_loop
    observer.z = 1.2
    loop.restart(1.2)
    setpoint, dt = setpoint_for_motion(motion, config), 0.02
    catch_up = config.motor_lag_s * config.uncertainty("heave") if motion else 0.0
    for k in range(40):
        observer.z = 1.2 + setpoint.climb_m_s * k * dt  # following its reference
        observer.disturbance = -5.0 if k < 5 else 0.0  # a force error past the motors' limit for 5 cycles, then none
        loop.step(k * dt, dt, setpoint, observer, controller.thrust, 1.0, False)
        since = k * dt - 4 * dt  # since the last cycle at the limit
        if since < catch_up - dt / 2:
            assert observer.freeze_disturbance, k
        elif since > catch_up + dt / 2:
            assert not observer.freeze_disturbance, k


def test_near_a_limit_the_climb_reference_slows_at_the_plans_braking_whatever_braking_the_model_leaves() -> None:
    """A weak corner's hold sets the disturbance near the motors' down authority, so the model leaves a climb no
    braking, and a reference slowed by the model alone held its climb rate into the limit (or climbed on through a
    `down`). It slows at least at the braking the limits' plan counts on, and reaches the plan's rate."""
    config = Config().flight
    controller = FlightController(config)
    observer, loop = controller.altitude, controller.altitude_loop
    observer.z, observer.vz = 2.3, 0.2
    loop.restart(2.3)
    lo, _ = controller.mixer.limits_up_n()
    controller.thrust.vertical = lo  # a hold at the motors' down limit lacking a little more: the disturbance
    observer.disturbance = -1.1 * (lo + config.net_buoyancy_n) / config.heave_mass
    up = setpoint_for_motion("up", config)
    for k in range(50):
        loop.step(k * 0.02, 0.02, up, observer, controller.thrust, 1.0, False)
    plan = math.sqrt(2.0 * loop._braking(observer, 1.0) * (config.altitude_max_m - 2.3 - 0.2 * (HANDOVER_S + config.motor_lag_s * 2.0)))
    assert loop.near_limit and loop.ref.rate <= plan + 0.002 < 0.19  # (main: 0.218 and rising)


@pytest.mark.parametrize("uncertainty", [2.0, 1.0])
def test_on_the_floor_with_the_disturbance_frozen_the_climb_rate_is_the_range_slope(uncertainty: float) -> None:
    """The body rests on the floor; then the loop pushes up against it, far below its target, where the disturbance
    learns nothing (a partner holding the body down must not wind it up). The model's push brought forward over the
    slope's age held the climb rate at +0.18 m/s with the rangefinder at 1 cm, the loop saw a climb and never pushed
    harder, and three random plants stayed on the floor (flight seeds 4-5; session 27). Frozen like that and marked
    (``touched``), the climb rate is the range slope: still."""
    config = replace(Config().flight, plant_uncertainty=uncertainty)
    dt = 1.0 / config.rate_hz
    rates = {}
    for touched in (True, False):
        observer = AltitudeObserver(config)
        for k in range(500):
            t = k * dt
            pushing = t > 6.0  # after the new hold's learning: the loop asks for 0.3 m/s^2 up
            observer.freeze_disturbance, observer.touched = pushing, pushing and touched
            observer.update(t, 0.01, -config.net_buoyancy_n + (0.3 * config.heave_mass if pushing else 0.0), dt)
        rates[touched] = observer.vz
    assert abs(rates[True]) < 0.005
    assert rates[False] > 0.1  # frozen but not marked (the code before): a believed climb


@pytest.mark.parametrize("uncertainty", [2.0, 1.0])
@pytest.mark.parametrize("true_accel", [0.15, 0.3, 0.6])
def test_lifting_off_the_floor_the_climb_rate_does_not_jump_when_the_slope_hands_back_to_the_model(
        uncertainty: float, true_accel: float) -> None:
    """While ``touched`` the climb rate is the range slope, 0.1-0.15 s old; once the body is back near its target the
    model-forward comparison takes over again (the session-27 review, finding 5). The body lifts off at 6 s, the loop
    asking for 0.3 m/s^2 while the body answers ``true_accel`` (the model's push, effectiveness untaught, far from the
    body's), and the hand-back at 6.5 s moves the climb rate by under 2 cm/s in its cycle. One cycle only: what the
    observer does after it is the model's error, which the flights judge."""
    config = replace(Config().flight, plant_uncertainty=uncertainty)
    dt = 1.0 / config.rate_hz
    observer = AltitudeObserver(config)
    lift, hand_back, floor = 6.0, 6.5, 0.3
    before = None
    for k in range(int(7.0 / dt)):
        t = k * dt
        rising = max(0.0, t - lift)
        pushing = t > 4.0
        observer.freeze_disturbance = observer.touched = pushing and t < hand_back
        observer.update(t, floor + 0.5 * true_accel * rising * rising,
                        -config.net_buoyancy_n + (0.3 * config.heave_mass if pushing else 0.0), dt)
        if abs(t - hand_back) < dt / 2:
            assert before is not None and abs(observer.vz - before) < 0.02
            assert abs(observer.vz - true_accel * (t - lift)) < 0.1  # and it was the body's rate, 0.1-0.15 s late
        before = observer.vz


def test_the_disturbance_learns_no_faster_than_its_slew_even_on_an_effectiveness_read_a_quarter_of_its_value() -> None:
    """A learning step is the miss over the learned effectiveness, and a side's first windows may read that a quarter
    of its value: corner-MTdL's first hover leapt from -0.46 to +0.38 m/s^2 (true -0.25) in half a second and the
    body fell to the floor (flight seed 52, session 30). Here a new hold on a body sinking at 0.4 m/s^2 the model does
    not know, with the position residual's slow integral off: the disturbance moves at most ``DISTURBANCE_SLEW_M_S3``
    (3.9 m/s^2 per s without it), and still most of a metre per second squared in the first second."""
    config = replace(Config().flight, disturbance_observer_hz=0.0)
    observer = AltitudeObserver(config)
    observer.effectiveness.values, observer.effectiveness.samples = [0.25, 0.25], [5, 5]
    dt, z, rate = 1.0 / config.rate_hz, 1.2, 0.0
    learned = []
    for k in range(round(2 * config.rate_hz)):
        rate -= 0.4 * dt
        z += rate * dt
        observer.update(10.0 + k * dt, round(z, 2), -config.net_buoyancy_n, dt)
        learned.append(observer.disturbance)
    assert max(abs(b - a) for a, b in zip(learned, learned[1:])) <= DISTURBANCE_SLEW_M_S3 * dt + 1e-12
    assert learned[round(config.rate_hz)] < -0.5
