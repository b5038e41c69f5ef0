"""The controller flying the simulated board faster than real time: hold, steps, commands, safety."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from feelium.daemon.config import Config
from feelium.lab.flight import scenarios as sc
from feelium.flight.sim_board import BoardParams, SensorParams, board_with
from feelium.flight.setpoint import HOLD, Setpoint, setpoint_for_motion
from feelium.lab.flight.simulation import SimFlight

pytestmark = pytest.mark.slow
# The tight goals are for a fitted model (what `feelium calibrate flight` writes): the plant is the config.
CONFIG = replace(Config().flight, plant_uncertainty=1.0)


def test_hold_in_still_air_meets_the_targets() -> None:
    result = sc.hold(CONFIG, drafts=False, seconds=15.0)
    assert result.altitude_rms_m <= 0.03
    assert result.heading_rms_deg <= 3.0


def test_hold_in_drafts_meets_the_targets() -> None:
    result = sc.hold(CONFIG, drafts=True, seconds=15.0)
    assert result.altitude_rms_m <= 0.08
    assert result.heading_rms_deg <= 3.0


def test_controller_is_much_quieter_than_an_untuned_pid() -> None:
    from feelium.lab.flight.baseline import BaselinePid

    ours = sc.hold(CONFIG, drafts=True, seconds=6.0)
    baseline = sc.hold(CONFIG, drafts=True, seconds=6.0, controller=BaselinePid(CONFIG))
    assert ours.roughness * 10 < baseline.roughness


def test_30_cm_climb_settles_within_4_s_with_little_overshoot() -> None:
    step = sc.altitude_step(CONFIG, 0.3, seconds=8.0)
    assert step.settling_s <= 4.0
    assert step.overshoot_fraction <= 0.10


def test_heading_step_settles_without_overshoot() -> None:
    step = sc.heading_step(CONFIG, 45.0, seconds=8.0)
    assert step.settling_s <= 4.0 and step.overshoot_fraction <= 0.10


@pytest.mark.parametrize("name", ["forward", "backward", "up", "down", "turn_left", "turn_right"])
def test_each_command_moves_the_right_way_and_stops_when_the_dead_man_lapses(name: str) -> None:
    result = sc.motion(CONFIG, name, hold_s=1.5)
    # Measured numbers are reported by `feelium bench flight`; here: it moves at once and it stops.
    assert result.latency_s < 0.3
    assert result.stop_s < 1.0


def test_release_holds_the_new_altitude_and_heading() -> None:
    flight = sc.new_flight(CONFIG, drafts=False)
    flight.run(4.0)
    flight.run(2.0, setpoint_for_motion("up", CONFIG))
    flight.run(2.0, setpoint_for_motion("turn_right", CONFIG))
    flight.run(3.0)
    z_after, heading_after = flight.board.state.z, flight.board.state.heading_deg
    flight.run(8.0)
    assert z_after > sc.START_ALTITUDE_M + 0.3
    assert abs(flight.board.state.z - z_after) < 0.03
    assert heading_after > 20.0
    assert abs(flight.board.state.heading_deg - heading_after) < 3.0


@pytest.mark.parametrize("name,start", [("up", 2.2), ("down", 0.8)])
def test_a_held_climb_or_descent_stops_at_the_altitude_limits(name: str, start: float) -> None:
    """Not at the ceiling or on the floor: `altitude_max_m`/`altitude_min_m` bound what up/down reach."""
    flight = sc.new_flight(CONFIG, drafts=False)
    flight.board.state = replace(flight.board.state, z=start)
    flight.run(4.0)
    first = len(flight.log["t"])
    flight.run(6.0, setpoint_for_motion(name, CONFIG))
    z = flight.log["z"][first:]
    if name == "up":
        assert CONFIG.altitude_max_m - 0.05 < z[-1] and z.max() < CONFIG.altitude_max_m + 0.03
    else:
        assert z[-1] < CONFIG.altitude_min_m + 0.05 and z.min() > CONFIG.altitude_min_m - 0.03
    assert abs(flight.board.state.w) < 0.05  # stopped there, still holding the command


def _held_then_released(config, hold_s: float) -> tuple[float, float]:
    flight = sc.new_flight(config, drafts=False)
    flight.run(5.0)
    board = flight.board
    board.state = replace(board.state, z=board.state.z - 0.3)  # a partner pulls it down 30 cm...
    board.held = True  # ...and holds it there
    flight.run(hold_s)
    board.held = False
    start = len(flight.log["t"])
    flight.run(8.0)
    z = flight.log["z"][start:]
    w = flight.log["w"][start:]
    return float(np.max(z) - sc.START_ALTITUDE_M), float(np.max(np.abs(w)))


def test_no_lunge_after_being_held_for_10_s() -> None:
    overshoot, peak_speed = _held_then_released(CONFIG, 10.0)
    # It returns to its altitude no faster than a gentle climb and does not shoot past it.
    assert overshoot < 0.05
    assert peak_speed < 0.4


def test_rangefinder_dropout_holds_briefly_then_floats_up_slowly() -> None:
    flight = sc.new_flight(CONFIG, drafts=False)
    flight.run(5.0)
    flight.board.params = replace(flight.board.params, sensors=SensorParams(range_dropout_probability=1.0))
    modes = [flight.step(HOLD).mode for _ in range(int(0.4 * CONFIG.rate_hz))]
    assert set(modes) == {"range_hold"}
    flight.run(4.0)
    assert flight.last is not None and flight.last.mode == "altitude_failsafe"
    assert 0.0 < flight.board.state.w < 0.6  # rising, gently (positively buoyant: never falls on anyone)
    flight.board.params = replace(flight.board.params, sensors=SensorParams(range_dropout_probability=0.0))
    flight.run(6.0)
    assert flight.last.mode == "flying"
    assert abs(flight.board.state.w) < 0.05  # and it holds again where it is


def test_link_loss_trips_the_board_watchdog_and_recovery_holds_the_new_altitude() -> None:
    flight = sc.new_flight(CONFIG, drafts=False)
    flight.run(5.0)
    flight.link_up = False
    flight.run(2.0)
    assert flight.board.watchdog_trips == 1
    assert flight.board.motors_us == (1500,) * 4
    assert flight.last is not None and flight.last.mode == "telemetry_failsafe"
    assert flight.board.state.z > sc.START_ALTITUDE_M + 0.2  # motors off: it floated up
    flight.link_up = True
    flight.run(6.0)
    assert flight.last.mode == "flying"
    z = flight.board.state.z
    flight.run(3.0)
    assert abs(flight.board.state.z - z) < 0.03


def test_soft_mode_yields_to_a_push_that_stiff_mode_resists() -> None:
    def displacement(soft: bool) -> float:
        flight = sc.new_flight(CONFIG, drafts=False)
        flight.run(5.0)
        flight.board.external_force_n = (0.0, 0.0, -0.08)  # a palm pressing it down
        flight.run(3.0, Setpoint(soften=soft))
        return sc.START_ALTITUDE_M - flight.board.state.z

    assert displacement(True) > 2 * displacement(False)


def test_soft_mode_ignores_wearer_motion() -> None:
    assert setpoint_for_motion("forward", CONFIG, soften=True) == Setpoint(soften=True)


def test_low_battery_is_reported() -> None:
    params = board_with(BoardParams(sensors=SensorParams(battery_capacity_mah=1.5)), z=1.2)
    flight = SimFlight(CONFIG, params)
    flight.run(3.0)
    assert flight.last is not None and flight.last.battery == "ok"
    flight.run(9.0)
    assert flight.last is not None and flight.last.battery in ("low", "critical")


def test_stale_telemetry_holds_the_last_output_briefly_then_fails_safe_upward() -> None:
    """The port stays open and motor commands still reach the board, but no telemetry arrives."""
    flight = sc.new_flight(CONFIG, drafts=False)
    flight.run(5.0)
    assert flight.last is not None
    hover = flight.last.commands[2]

    def blind_step() -> str:
        flight.clock.t = round(flight.clock.t + flight.period, 9)
        flight.board.advance_to(flight.clock.t)
        out = flight.controller.step(flight.clock.t, None, HOLD)
        flight.client.send_motors(out.motors_us)
        flight.last = out
        return out.mode

    held = [blind_step() for _ in range(int(0.25 * CONFIG.rate_hz))]
    assert set(held) == {"range_hold"}
    assert flight.last.commands[2] == pytest.approx(hover, abs=0.02)  # the last safe output, held
    failsafe = [blind_step() for _ in range(int(2.0 * CONFIG.rate_hz))]
    assert failsafe[-1] == "telemetry_failsafe"
    assert flight.last.commands[2] < hover - 0.005  # less down-thrust (90 % of the buoyancy cancelled): it rises...
    assert 0.0 < flight.board.state.w < 0.6  # ...slowly, never down onto people
    flight.run(6.0)  # telemetry is back
    assert flight.last.mode == "flying"
    z = flight.board.state.z
    flight.run(3.0)
    assert abs(flight.board.state.z - z) < 0.03  # and it holds where it came to rest
