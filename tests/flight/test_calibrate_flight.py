"""`feelium calibrate flight`: the fit's pieces on exact data, the scripted flight's safety, the CLI end to end."""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import tomllib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.daemon.config import Config, load_config
from feelium.flight import messages as m
from feelium.flight.sim_board import BoardParams, SensorParams
from feelium.flight.config import FlightConfig
from feelium.flight.estimators import SurgeEstimate
from feelium.flight.telemetry import Telemetry
from feelium.flight.sysid import Estimate, FlightRecord, PlantFit, lagged_mean, least_squares, motor_shape, prepare, smooth
from feelium.flight.blimp_model import BlimpParams
from feelium.lab.flight.calibrate import (MAX_FLIGHT_S, NothingFlown, axis_uncertainties, braked, calibrate_from, calibrate_sim, fly,
                                          hover_guess, recovery_errors, render_calibrated, sim_run, summary, tight_goals)
from feelium.lab.flight.plants import describe, plant_set
from feelium.lab.flight.calibration_pilot import CalibrationPilot, Step, default_script

CONFIG = Config().flight


@given(lag=st.floats(0.03, 0.2), level=st.floats(-1.0, 1.0))
def test_lagged_mean_is_the_exact_period_mean_of_a_first_order_lag(lag: float, level: float) -> None:
    dt = 0.02
    steady = np.full(40, level)
    steady[:5] = 0.0
    means = lagged_mean(steady, lag, dt)
    fine = 200  # integrate the lag finely: the mean over period k of a lag started at 0 at t = 5 dt
    for k in (5, 6, 10, 30):
        tt = (np.arange(fine) + 0.5) / fine * dt + (k - 5) * dt
        assert means[k] == pytest.approx(level * np.mean(1.0 - np.exp(-tt / lag)), abs=1e-6)


@settings(max_examples=20, deadline=None)
@given(start=st.floats(0.0, 1000.0), period=st.sampled_from([0.02, 0.01, 0.025]))
def test_each_tick_keeps_its_own_command_on_the_fit_grid_however_the_ticks_round(start: float, period: float) -> None:
    """The flight's ticks accumulate a float period (``tick += period``, as ``fly`` does), so the fit's uniform
    grid drifts a hair before or after them; each grid point must still hold its own tick's command. Taking
    the previous one there delayed every command by a period from about 208 s of a flight on (session 14)."""
    n = 15000
    t = np.empty(n)
    tick = start
    for k in range(n):
        t[k] = tick
        tick += period
    commands = np.random.default_rng(1).uniform(-1.0, 1.0, (n, 4))
    readings = np.ones(n)
    record = FlightRecord(t, commands, readings, readings, readings)
    np.testing.assert_array_equal(prepare(record).commands, commands)


def test_motor_shape_is_zero_in_the_deadband_and_quadratic_beyond_it() -> None:
    fwd, rev = motor_shape(np.array([0.05, 0.1, 0.55, 1.0, -0.55, -1.2]), 0.1)
    assert list(fwd[:4]) == pytest.approx([0.0, 0.0, 0.25, 1.0])
    assert list(rev[4:]) == pytest.approx([0.25, 1.0])
    assert fwd[4:].sum() == 0.0 and rev[:4].sum() == 0.0


@settings(max_examples=25, deadline=None)
@given(a=st.floats(0.2, 3.0), b=st.floats(0.2, 3.0), seed=st.integers(0, 2**16))
def test_least_squares_recovers_coefficients_and_honest_errors(a: float, b: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x1, x2 = rng.normal(size=4000), rng.normal(size=4000)
    noise = smooth(rng.normal(scale=0.05, size=4000), 3.0)[0]
    fit = least_squares({"a": x1, "b": x2}, a * x1 + b * x2 + noise, np.ones(4000, bool), 3.0)
    for name, truth in (("a", a), ("b", b)):
        e = fit.estimate(name)
        assert abs(e.value - truth) < 5.0 * e.stderr + 1e-9


def _fit_with_errors(**relative: float) -> PlantFit:
    names = ("surge_thrust_per_mass", "yaw_torque_per_inertia", "heave_thrust_per_mass", "heave_mass_kg",
             "horizontal_reverse_ratio", "vertical_reverse_ratio")
    return PlantFit({name: Estimate(2.0, 2.0 * relative.get(name, 0.0)) for name in names})


def test_each_axis_gets_the_smallest_box_that_holds_its_own_3_sigma_errors() -> None:
    axes = axis_uncertainties(_fit_with_errors(surge_thrust_per_mass=0.05, horizontal_reverse_ratio=0.05,
                                               yaw_torque_per_inertia=0.1, vertical_reverse_ratio=0.3, heave_thrust_per_mass=0.02))
    # surge: U^2 >= 1.15 (thrust per mass) and U^3 >= 1.15 x 1.15 (a reverse push); yaw likewise with 1.3
    assert axes["surge"] == pytest.approx(math.ceil(100 * 1.15 ** (2 / 3)) / 100)
    assert axes["yaw"] == pytest.approx(math.ceil(100 * (1.3 * 1.15) ** (1 / 3)) / 100)
    # heave: its box is U^+-2 both ways, and an upward push carries the reverse ratio's error: the loose
    # vertical reverse ratio widens the heave's box only
    assert axes["heave"] == pytest.approx(math.ceil(100 * math.sqrt(1.06 * 1.9)) / 100)
    assert axes["surge"] <= 1.1 < axes["heave"]
    assert axis_uncertainties(_fit_with_errors(surge_thrust_per_mass=5.0))["surge"] == 4.0  # capped
    # the heave's at the shipped learning box: wider, its loop started 13-16 times too timid and never learned
    assert axis_uncertainties(_fit_with_errors(vertical_reverse_ratio=3.0, heave_thrust_per_mass=0.1))["heave"] == 2.0
    assert axis_uncertainties(_fit_with_errors()) == {"heave": 1.0, "surge": 1.0, "yaw": 1.0}  # an exact fit is trusted


def test_the_brake_a_calibration_shows_is_its_measured_reverse_thrust_per_mass_3_sigma_low_over_the_models() -> None:
    """The surge fit's own reverse thrust per mass (per motor), divided by 1 + 3 x its relative error (the boxes'
    3 sigma), over what the written config models: its reverse thrust over its surge mass."""
    from feelium.lab.flight.calibrate import brake_shown

    config = FlightConfig(mass_kg=1.0, horizontal_thrust_n=0.2, horizontal_reverse_ratio=0.5)  # models 0.1 m/s^2 per motor
    assert brake_shown(PlantFit({"surge_reverse_thrust_per_mass": Estimate(0.12, 0.012)}), config) == 0.923  # 0.12 / 1.3 / 0.1, down
    assert brake_shown(PlantFit({"surge_reverse_thrust_per_mass": Estimate(0.1, 0.0)}), config) == pytest.approx(1.0)
    assert brake_shown(PlantFit({"surge_reverse_thrust_per_mass": Estimate(-0.01, 0.01)}), config) == 0.0  # nothing shown
    assert brake_shown(PlantFit({"surge_reverse_thrust_per_mass": Estimate(0.1, 0.01)}), FlightConfig(horizontal_reverse_ratio=0.0)) == 0.0


def test_the_deadband_compensated_is_each_pair_s_fit_2_sigma_low_and_never_negative() -> None:
    """Compensated too wide, a deadband pushes more than asked at every small force (calibrated corner-mtDL s10: a
    first forward at 1.24 of the command, session 25); too narrow pushes less, which the loops make up."""
    from feelium.lab.flight.calibrate import low_deadband

    fit = PlantFit({"horizontal_deadband": Estimate(0.19, 0.0687), "vertical_deadband": Estimate(0.05, 0.04)})
    assert low_deadband(fit, "horizontal_deadband") == pytest.approx(0.19 - 2 * 0.0687)
    assert low_deadband(fit, "vertical_deadband") == 0.0  # 2 sigma below zero: none compensated


def test_a_fit_no_blimp_can_have_is_named_and_a_physical_one_passes() -> None:
    """calibrated corner-MtdL at flight seed 15 fitted a negative surge mass, thrust and yaw inertia with boxes of 1.3,
    and the controller dividing by them never stopped the blimp (session 25): such a fit is reported, not flown."""
    from dataclasses import replace

    from feelium.lab.flight.calibrate import unphysical

    assert unphysical(FlightConfig()) == [] and unphysical(replace(FlightConfig(), vertical_reverse_ratio=0.0)) == []
    bad = replace(FlightConfig(), mass_kg=-0.0716, horizontal_thrust_n=-0.0066, yaw_inertia_kg_m2=float("nan"),
                  vertical_reverse_ratio=float("nan"))
    assert [p.split(" = ")[0] for p in unphysical(bad)] == [
        "mass_kg", "heave_mass", "yaw_inertia_kg_m2", "horizontal_thrust_n", "vertical_reverse_ratio"]  # heave: mass_kg's


def test_an_axis_uncertainty_overrides_plant_uncertainty_for_that_axis_only() -> None:
    config = FlightConfig(plant_uncertainty=2.0, surge_uncertainty=1.1)
    assert (config.uncertainty("surge"), config.uncertainty("yaw"), config.uncertainty("heave")) == (1.1, 2.0, 2.0)
    assert FlightConfig(plant_uncertainty=1.5, yaw_uncertainty=0.5).uncertainty("yaw") == 1.0
    # and the surge estimate's learning box is the surge's: 1.1^-3 .. 1.1^2 for a reverse push
    effectiveness = SurgeEstimate(config).effectiveness
    assert effectiveness.high == pytest.approx(1.21) and effectiveness.lows[0] == pytest.approx(1.1**-3)


EXACT_SENSORS = SensorParams(range_noise_m=0.0, range_noise_fraction=0.0, range_dropout_probability=0.0, gyro_noise_dps=0.0,
                             gyro_bias_dps=0.0, flow_noise_rad_s=0.0)


def test_the_scripted_flight_ends_neutral_and_stays_in_its_envelope() -> None:
    run = sim_run(BoardParams(sensors=EXACT_SENSORS), seed=3)
    pilot = CalibrationPilot(hover_command=hover_guess(CONFIG))
    heights: list[float] = []

    def wait(t: float) -> None:
        run.wait_until(t)
        heights.append(run.board.state.z)

    log = fly(run.client, pilot, run.clock, wait, 0.02)
    assert pilot.done and pilot.aborted is None
    assert pilot.skipped == [6, 7]  # the paper's blimp is brisk: the +-0.65 pair moved it, no +-0.85 pair
    assert len(pilot.segments) + len(pilot.skipped) == len(pilot.script)
    assert 60.0 < log.rows[-1][0] < MAX_FLIGHT_S  # a few minutes of flight
    assert run.board.motors_us[:4] == m.NEUTRAL_MOTORS_US[:4]
    # The steps end at 0.7 and 2.2 m; the hold catches them inside the altitude limits a user may fly to.
    assert CONFIG.altitude_min_m < min(heights) and max(heights) < CONFIG.altitude_max_m


@pytest.mark.parametrize("how", ["stop", "exception"])
def test_an_aborted_flight_leaves_the_motors_neutral(how: str) -> None:
    run = sim_run(BoardParams(), seed=2)
    pilot = CalibrationPilot(hover_command=hover_guess(CONFIG))

    def should_stop() -> str | None:
        if run.clock.t >= 12.0:  # inside the first surge step: horizontal motors running
            assert run.board.motors_us[0] != m.MOTOR_NEUTRAL_US
            if how == "exception":
                raise KeyboardInterrupt
            return "stop"
        return None

    if how == "exception":
        with pytest.raises(KeyboardInterrupt):
            fly(run.client, pilot, run.clock, run.wait_until, 0.02, should_stop=should_stop)
    else:
        fly(run.client, pilot, run.clock, run.wait_until, 0.02, should_stop=should_stop)
        assert pilot.aborted == "stop"
    run.board.advance_to(run.clock.t + 0.01)
    assert run.board.motors_us[:4] == m.NEUTRAL_MOTORS_US[:4]


def test_braking_is_shown_only_by_a_flown_reverse_surge_step() -> None:
    pilot = CalibrationPilot(hover_command=0.0)
    assert [(step.axis, step.level) for step in pilot.script[:2]] == [("surge", 0.25), ("surge", -0.25)]
    assert not braked(pilot)  # nothing flown (a flight stopped at once)
    pilot.segments.append((0, 6.0, 9.0))
    assert not braked(pilot)  # forward only
    pilot.segments.append((1, 15.0, 18.0))
    assert braked(pilot)


def _toy_surge_flight(accel_per_command: float, script: list[Step], seconds: float = 120.0) -> CalibrationPilot:
    """The pilot alone flying ``script`` on a toy body whose forward acceleration is ``accel_per_command`` x the
    mean horizontal command (1.45 m up, no yaw, no drafts), fed the flow it would read."""
    pilot = CalibrationPilot(hover_command=0.0, script=script)
    u, t = 0.0, 0.0
    while not pilot.done and t < seconds:
        left, right, _, _ = pilot.step(t, Telemetry(t, range_m=1.45, yaw_rate_dps=0.0, flow_x_rad_s=u / 1.45))
        u += accel_per_command * 0.5 * (left + right) * 0.02
        t += 0.02
    assert pilot.done and pilot.aborted is None
    return pilot


def _surge_step_lengths(accel_per_command: float) -> list[float]:
    """The flown lengths of a held-on surge pair on the toy body."""
    script = [Step("surge", 0.5, 1.0, extend_s=2.0), Step("surge", -0.5, 1.0, extend_s=2.0)]
    return [round(end - start, 2) for _, start, end in _toy_surge_flight(accel_per_command, script).segments]


def test_a_surge_step_that_barely_moves_the_body_is_held_on_and_a_brisk_one_is_not() -> None:
    """A heavy, weak plant's surge steps drowned in the drafts (its reverse ratio fitted +-30 %): a step that has
    changed the speed by less than ``surge_change_m_s`` runs its ``extend_s`` too; one that has, ends on time."""
    assert _surge_step_lengths(0.05) == pytest.approx([3.0, 3.0], abs=0.03)  # one tick; 0.025 m/s^2: 0.075 m/s after 3 s
    assert _surge_step_lengths(0.5) == pytest.approx([1.0, 1.0], abs=0.03)  # 0.25 m/s^2: 0.25 m/s after 1 s


def test_the_bigger_surge_pair_flies_only_when_the_pair_before_it_barely_moved_the_body() -> None:
    """On a light plant the +-0.85 pair was a sub-second step cut by the speed guard (deadband and reverse ratio
    fitted worse): an ``only_if_weak`` step flies only if the pair before it changed the speed by less than
    ``surge_change_m_s``."""
    weak_only = [Step("surge", 0.8, 1.0, only_if_weak=True), Step("surge", -0.8, 1.0, only_if_weak=True)]
    script = [Step("surge", 0.5, 1.0, extend_s=2.0), Step("surge", -0.5, 1.0, extend_s=2.0), *weak_only]
    brisk = _toy_surge_flight(0.5, script)  # 0.25 m/s after 1 s
    assert [index for index, _, _ in brisk.segments] == [0, 1] and brisk.skipped == [2, 3]
    assert min(brisk.surge_changes.values()) >= brisk.envelope.surge_change_m_s
    weak = _toy_surge_flight(0.05, script)  # 0.075 m/s after 3 s
    assert [index for index, _, _ in weak.segments] == [0, 1, 2, 3] and weak.skipped == []
    assert max(weak.surge_changes[i] for i in (0, 1)) < weak.envelope.surge_change_m_s


def test_only_the_big_surge_steps_are_held_on_however_little_the_small_ones_moved_the_body() -> None:
    """A +-0.25 or +-0.45 step held on sat at a terminal speed of a few cm/s on the light draggy corners, where
    the fit ties the push to a drag the drafts hide: their horizontal deadband came out 27-70 % high (session 18).
    On a body every step barely moves (0.03 m/s^2 per command: 0.077 m/s after 3 s at 0.85), the default script's
    small steps run their 3 s and only the +-0.65 and +-0.85 pairs are held on, to 6 s."""
    script = [step for step in default_script() if step.axis == "surge"]
    weak = _toy_surge_flight(0.03, script, seconds=240.0)
    lengths = {script[index].level: round(end - start, 2) for index, start, end in weak.segments}
    assert weak.skipped == [] and max(weak.surge_changes.values()) < weak.envelope.surge_change_m_s
    assert lengths == pytest.approx({0.25: 3.0, -0.25: 3.0, 0.45: 3.0, -0.45: 3.0, 0.65: 6.0, -0.65: 6.0, 0.85: 6.0, -0.85: 6.0}, abs=0.03)


def test_the_script_at_its_longest_ends_before_the_flight_time_limit() -> None:
    """Every step held to its extension and every settle to its maximum: still inside ``MAX_FLIGHT_S``."""
    pilot = CalibrationPilot(hover_command=0.0)
    longest = pilot.gains.settle_max_s * (len(pilot.script) + 1) + sum(s.seconds + s.extend_s for s in pilot.script)
    assert 240.0 < longest < MAX_FLIGHT_S


def _noise_free() -> dict[str, Any]:
    cal = calibrate_sim(CONFIG, drafts=False, sensors=EXACT_SENSORS)
    return {"errors": recovery_errors(cal.fit, BlimpParams()), "lag": (cal.config.motor_lag_s, cal.fit.value("motor_lag_s"))}


def _random_plant(index: int) -> dict[str, Any]:
    plant = plant_set(index + 1)[index]
    cal = calibrate_sim(CONFIG, plant.blimp)
    return {"errors": recovery_errors(cal.fit, plant.blimp), "goals": tight_goals(cal.config, plant.blimp),
            "uncertainty": cal.config.plant_uncertainty, "describe": describe(plant)}  # fmt: skip


def _corner_after_calibration() -> dict[str, Any]:
    from feelium.lab.flight.safety import safety_flight

    plant = plant_set(4)[3]
    return {"name": plant.name, "result": safety_flight(calibrate_sim(CONFIG, plant.blimp).config, plant)}


def _heavy_corner_after_calibration() -> dict[str, Any]:
    from feelium.lab.flight.safety import safety_flight

    plant = plant_set(10)[9]
    config = calibrate_sim(CONFIG, plant.blimp).config
    return {"name": plant.name, "config": config, "result": safety_flight(config, plant), "goals": tight_goals(config, plant.blimp),
            "goals_unmeasured_brake": tight_goals(replace(config, surge_brake_shown=0.0), plant.blimp)}


def _heavy_corner_at_seed_3() -> dict[str, Any]:
    from feelium.lab.flight.safety import safety_flight

    plant = plant_set(10)[9]
    return {"name": plant.name, "result": safety_flight(calibrate_sim(CONFIG, plant.blimp, seed=3).config, plant, seed=3)}


def _heavy_corner_on_a_thrust_stand() -> dict[str, Any]:
    from feelium.flight.sysid import identify

    plant = plant_set(10)[9]
    stand = 1.05 * plant.blimp.horizontal_motor.max_thrust_n  # a reading 5 % high: the figure's stated error
    cal = calibrate_sim(CONFIG, plant.blimp, stand_thrust_n=Estimate(stand, 0.05 * stand))
    flown = cal.config  # the config the fit started from carries the weighed buoyancy calibrate_sim used
    through_heave, _, _ = identify(cal.record, flown.net_buoyancy_n, flown.arm_m, flown.altitude_min_m - 0.4, flown.altitude_max_m + 0.4)
    return {"name": plant.name, "stand": recovery_errors(cal.fit, plant.blimp), "heave": recovery_errors(through_heave, plant.blimp),
            "scale": summary(cal)["horizontal_scale"], "toml": render_calibrated(Config(), cal)}


def _light_strong_draggy_corner_at_seed_14() -> dict[str, Any]:
    from feelium.lab.flight.safety import safety_flight

    plant = plant_set(8)[7]
    return {"name": plant.name, "result": safety_flight(calibrate_sim(CONFIG, plant.blimp, seed=14).config, plant, seed=14)}


# Each calibration flies minutes of simulated flight; independent and seeded, they run on every core at once
# (the same results as one after another).
HEAVY: dict[str, tuple[Any, ...]] = {
    "noise-free": (_noise_free,), "random-16": (_random_plant, 16), "random-17": (_random_plant, 17),
    "corner-mtDL": (_corner_after_calibration,), "corner-MtdL": (_heavy_corner_after_calibration,),
    "corner-MtdL-s3": (_heavy_corner_at_seed_3,), "corner-mTDL-s14": (_light_strong_draggy_corner_at_seed_14,),
    "corner-MtdL-stand": (_heavy_corner_on_a_thrust_stand,),
}  # fmt: skip


def _run(job: tuple[Any, ...]) -> Any:
    return job[0](*job[1:])


@pytest.fixture(scope="module")
def heavy(request: pytest.FixtureRequest) -> dict[str, Any]:
    """The heavy calibrations the selected tests need, flown in parallel."""
    wanted = sorted({name for item in request.session.items if item.module is request.module
                     for name in getattr(item.function, "heavy", ())})  # fmt: skip
    workers = max(1, min(len(os.sched_getaffinity(0)), 4, len(wanted)))
    if workers == 1:
        return {name: _run(HEAVY[name]) for name in wanted}
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        return dict(zip(wanted, pool.map(_run, [HEAVY[name] for name in wanted])))


def needs(*names: str) -> Any:
    """Mark a test with the heavy calibrations it reads from the ``heavy`` fixture."""

    def mark(test: Any) -> Any:
        test.heavy = names
        return test

    return mark


@needs("noise-free")
def test_on_noise_free_sensors_in_still_air_every_parameter_but_the_drags_split_is_within_10_percent(heavy) -> None:  # type: ignore[no-untyped-def]
    """The paper's blimp, sensors without noise (the rangefinder still reports whole cm, the gyro whole deg/s),
    no drafts: the method itself is unbiased to 10 %. The linear drag, a few percent of the force at these
    speeds, is the exception (its quadratic partner and the drag at cruise are checked instead)."""
    errors = heavy["noise-free"]["errors"]
    assert {k: round(e, 3) for k, e in errors.items() if abs(e) > 0.10 and k not in ("linear_drag_n_per_m_s", "yaw_linear_drag")} == {}
    written, fitted = heavy["noise-free"]["lag"]
    assert written == pytest.approx(fitted, abs=1e-4)  # written for the controller


# The first two random plants of the set (16 and 17; the corners are the box's extremes, the bench reports all).
# Measured on the set's first 20 plants (docs/calibrate-flight.md): these two are within 10 % on 19 of them
# (worst 13 %, a heavy slow corner); the others are not, and the bench reports them.
RECOVERED = ("heave_mass_kg", "vertical_thrust_n")


# 16: the fitted surge model is 10 % off (horizontal thrust -9 %): cruise 0.93 now that the speed estimate follows the
# flow within a held command (0.89 before). 17: its loose vertical reverse ratio (+-17 %) no longer widens the
# surge's box: cruise 0.97 (0.59 with one uncertainty for all axes).
@pytest.mark.slow
@pytest.mark.parametrize("index", [16, 17])
@needs("random-16", "random-17")
def test_on_randomised_plants_the_buoyancy_scaled_parameters_are_recovered_and_the_tight_goals_met(index: int, heavy) -> None:  # type: ignore[no-untyped-def]
    done = heavy[f"random-{index}"]
    errors = done["errors"]
    assert {k: round(errors[k], 3) for k in RECOVERED if abs(errors[k]) > 0.10} == {}, done["describe"]
    goals = done["goals"]
    assert goals["altitude_rms_m"] <= 0.03 and goals["heading_rms_deg"] <= 3.0
    assert abs(goals["cruise_fraction"] - 1.0) <= 0.10, (goals, done["uncertainty"])


@pytest.mark.slow
def test_cli_on_the_simulator_writes_a_loadable_config_a_report_and_plots(tmp_path: Path) -> None:
    from feelium.cli import main

    assert main(["calibrate", "flight", "--sim", "--out", str(tmp_path)]) == 0
    fitted = load_config(tmp_path / "flight-calibrated.toml").flight
    assert fitted.heave_mass_kg > 0.0 and fitted.plant_uncertainty >= 1.0
    assert fitted.braking_shown  # the script flies reverse surge steps: the speed cap may count on the fit
    text = (tmp_path / "flight-calibrated.toml").read_text()
    assert "# fitted: +-" in text and "residual heave" in text
    for axis in ("heave", "surge", "yaw"):
        assert (tmp_path / f"calibrate-{axis}.png").stat().st_size > 1000
    assert tomllib.loads(text)["flight"]["mass_kg"] == fitted.mass_kg
    assert math.isfinite(fitted.vertical_thrust_n)


def test_cli_reports_a_fit_no_blimp_can_have_writes_no_config_and_keeps_the_report(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """The heavy weak corner-MtdL (plant 9) at seed 15 fits a negative surge mass (session 25): the user gets exit 1,
    the values named, the report and plots kept (nothing recorded is lost), and no config to fly."""
    from feelium.cli import main

    assert main(["calibrate", "flight", "--sim", "--plant", "9", "--seed", "15", "--out", str(tmp_path)]) == 1
    assert not (tmp_path / "flight-calibrated.toml").exists()
    report = json.loads((tmp_path / "calibration.json").read_text())
    assert any(problem.startswith("mass_kg = -") for problem in report["problems"])
    err = capsys.readouterr().err
    assert "no config written" in err and "calmer air" in err
    assert (tmp_path / "calibrate-surge.png").stat().st_size > 1000


@pytest.mark.slow
@needs("corner-mtDL")
def test_with_its_fitted_config_the_light_draughty_corner_stops_a_turn_in_time(heavy) -> None:  # type: ignore[no-untyped-def]
    """corner-mtDL (light, weak, high drag, long lag) with its fitted config: after a turn a draft drifted the
    body backwards past 5 cm/s while the hover band, deciding on the model-led estimate, saw -2 cm/s, and the
    stop took 2.28 s. The band now decides on the flow (`SurgeEstimate.decision_speed`): 0.48 s, measured.
    Its hover reversals meet the goal since session 10 (0.33 /s, measured; 0.6 before the reversal guard kept
    the pair's yaw torque and the hover heading loop acted on the gyro-smoothed heading)."""
    from feelium.lab.flight.safety import GOALS

    assert heavy["corner-mtDL"]["name"] == "corner-mtDL"
    result = heavy["corner-mtDL"]["result"]
    assert result.stop_s <= GOALS["stop_s"] and result.lapse_s <= GOALS["lapse_s"], result.manoeuvres
    assert result.speed_peak_fraction <= GOALS["speed_peak_fraction"]
    assert result.turn_peak_fraction <= GOALS["turn_peak_fraction"]
    assert result.altitude_excursion_m <= GOALS["altitude_excursion_m"]
    assert result.hover_reversals_per_s <= GOALS["hover_reversals_per_s"]


@pytest.mark.slow
@needs("corner-MtdL")
def test_with_its_fitted_config_a_heavy_weak_corner_cruises_on_its_measured_brake_and_still_stops_in_time(heavy) -> None:  # type: ignore[no-untyped-def]
    """corner-MtdL (heavy, weak, long lag) cannot stop the commanded 0.15 m/s within 1.0 s (v_stop 0.118 m/s: the
    cruise is judged against that). Its calibration measured its brake (``surge_brake_shown`` 0.757), and the cap counts
    on 0.8 of it: cruise 0.408 of the command, measured (0.347 with the same fit's brake unmeasured: 1/U at the ordinary
    0.55 share), while every safety goal holds (stop 0.56 s) and it never cruises faster than the plant can stop from.
    (Judged against that same-seed variant since session 32: the absolute 0.41 this asserted was passed by 0.0003, and
    the cruise integral, which cruises at the cap on the flow, moved it to 0.4075 on the flow's noise.)"""
    from feelium.lab.flight.safety import GOALS

    done = heavy["corner-MtdL"]
    assert done["name"] == "corner-MtdL" and done["config"].surge_brake_shown > 0.0
    assert done["result"].failures() == {}, done["result"].manoeuvres
    goals = done["goals"]
    assert goals["cruise_target_m_s"] == goals["v_stop_m_s"] < done["config"].forward_speed_m_s
    assert goals["cruise_fraction"] > 1.1 * done["goals_unmeasured_brake"]["cruise_fraction"]  # 0.408 against 0.347
    assert goals["cruise_fraction_of_target"] <= 1.0 and done["result"].stop_s <= GOALS["stop_s"]


@pytest.mark.slow
@needs("corner-MtdL-s3")
def test_with_its_fitted_config_a_heavy_weak_corner_stops_a_held_climb_inside_the_ceiling_limit(heavy) -> None:  # type: ignore[no-untyped-def]
    """corner-MtdL calibrated and flown at seed 3 (heavy, weak, lag 150 ms; it hovers with its vertical motors at 0.8
    of their 0.9 down limit): three noise-sized windows of the held climb's onset taught the heave's margin a brake 2.5
    times the body's, the disturbance wound up on and off the down limit until the model left the climb no braking,
    and the body went 0.40 m through the ceiling limit (goal 0.10; the shipped config flies it clean). Now 0.000 m
    and every safety goal (0.045 m with the altitude loop's changes alone, 0.022 m with the heave box capped at 2
    alone; docs/calibrate-flight.md, session 22)."""
    from feelium.lab.flight.safety import GOALS

    done = heavy["corner-MtdL-s3"]
    assert done["name"] == "corner-MtdL"
    assert done["result"].altitude_excursion_m <= GOALS["altitude_excursion_m"]
    assert done["result"].failures() == {}, done["result"].manoeuvres


@pytest.mark.slow
@needs("corner-mTDL-s14")
def test_with_its_fitted_config_a_draggy_corner_in_a_tailwind_keeps_its_held_speed_within_the_goal(heavy) -> None:  # type: ignore[no-untyped-def]
    """corner-mTDL calibrated and flown at seed 14 (light, strong, draggy, lag 150 ms), held out for session 25's
    changes: a tailwind took the body's drag away during the first `forward` and the estimate, trusting the fitted
    model for 0.37 s, read 0.163 m/s with the body at 0.181: a speed peak of 1.209. A held command is now steered on
    the flow-led speed when that says faster along the command (``SurgeEstimate.held_speed``): 1.172, measured."""
    from feelium.lab.flight.safety import GOALS

    done = heavy["corner-mTDL-s14"]
    assert done["name"] == "corner-mTDL"
    assert done["result"].speed_peak_fraction <= GOALS["speed_peak_fraction"], done["result"].manoeuvres
    assert done["result"].failures() == {}, done["result"].manoeuvres


@pytest.mark.slow
@needs("corner-MtdL-stand")
def test_a_thrust_stand_figure_scales_the_surge_mass_and_yaw_inertia_where_the_heave_drag_could_not(heavy) -> None:  # type: ignore[no-untyped-def]
    """corner-MtdL (heavy, weak, long lag), one calibration flight fitted both ways. Through the heave drag (no stand
    figure) its surge mass came out 22 % high and its yaw inertia 20 %: the drafts blur the drag that carries the
    scale. With one horizontal motor's full thrust read on a thrust stand 5 % high (its stated error), the surge mass is
    that thrust over the fitted thrust per mass: within 10 %, and the yaw inertia with it (measured: 7 % and 5 %). The
    vertical values keep the weighed buoyancy's scale, and the report says which scale was used."""
    done = heavy["corner-MtdL-stand"]
    assert done["name"] == "corner-MtdL"
    for name in ("surge_mass_kg", "yaw_inertia_kg_m2"):
        assert abs(done["stand"][name]) <= 0.10, (name, done["stand"][name], done["heave"][name])
    assert done["stand"]["horizontal_thrust_n"] == pytest.approx(0.05)  # the figure itself, 5 % high
    assert done["stand"]["heave_mass_kg"] == done["heave"]["heave_mass_kg"]
    assert done["scale"] == "thrust stand" and "horizontal scale: the thrust stand" in done["toml"]


@pytest.mark.parametrize("flags", [["--stand-thrust-n", "-0.2"], ["--stand-thrust-n", "nan"], ["--stand-thrust-n", "25"],
                                   ["--stand-thrust-n", "0.25", "--stand-error", "0"], ["--stand-error", "0.05"]],
                         ids=["negative", "nan", "grams", "no-error", "error-alone"])
def test_cli_refuses_a_thrust_stand_figure_no_stand_reads_before_flying(flags: list[str], tmp_path: Path) -> None:
    from feelium.cli import main

    with pytest.raises(SystemExit, match="--stand-"):
        main(["calibrate", "flight", "--sim", "--out", str(tmp_path), *flags])
    assert not any(tmp_path.iterdir())


def _flown_until(stop_s: float) -> tuple[Any, CalibrationPilot]:
    """The calibration flight on the paper's blimp, stopped with ``stop`` at ``stop_s``."""
    run = sim_run(BoardParams(), seed=2)
    pilot = CalibrationPilot(hover_command=hover_guess(CONFIG))
    log = fly(run.client, pilot, run.clock, run.wait_until, 0.02, should_stop=lambda: "stop" if run.clock.t >= stop_s else None)
    return log, pilot


def test_a_flight_stopped_before_its_script_ended_is_fitted_for_the_report_but_never_gives_a_config() -> None:
    """Stopped 45 s in, before any yaw step, the fit's yaw came out of nothing: a yaw drag 160 times the shipped one
    in boxes of 1.14-1.29, and the blimp flown with it spun at six times the commanded turn and never stopped (the
    session-32 review, finding 1). The fit is still made and reported (nothing recorded is lost), the config stays the
    one flown with."""
    log, pilot = _flown_until(45.0)
    assert pilot.aborted == "stop" and pilot.segments
    assert not any(pilot.script[index].axis == "yaw" for index, _, _ in pilot.segments)
    calibration = calibrate_from(log, pilot, CONFIG)
    assert calibration.problems[0].startswith("the flight was stopped before its script ended (stop)")
    assert calibration.config is CONFIG
    assert summary(calibration)["aborted"] == "stop"


def test_a_flight_stopped_before_its_first_step_says_there_is_nothing_to_fit() -> None:
    """Stopped in its first settle, the fit had no step and failed with an IndexError deep in the resampling."""
    log, pilot = _flown_until(1.0)
    with pytest.raises(NothingFlown, match="before its first step"):
        calibrate_from(log, pilot, CONFIG)


def test_a_board_that_never_answers_ends_the_flight_neutral_within_its_first_telemetry_time() -> None:
    """A port that opens and stays silent kept the flight waiting, motors neutral, for its whole 360 s: the telemetry
    timeout armed only after a first reply."""
    pilot = CalibrationPilot(hover_command=0.3)
    t = 10.0
    while not pilot.done and t < 20.0:
        assert pilot.step(t, None) == (0.0, 0.0, 0.0, 0.0)
        t = round(t + 0.02, 9)
    assert pilot.aborted == "no telemetry: the board never answered"
    assert t <= 10.0 + pilot.envelope.first_telemetry_s + 0.05


@pytest.mark.parametrize("flags, says", [(["--plant", "-1"], "0 or more"), (["--seed", "-1"], "0 or more"),
                                         (["--port", "/dev/null", "--seed", "3"], "they need --sim")],
                         ids=["negative-plant", "negative-seed", "seed-on-a-board"])
def test_cli_refuses_arguments_no_plant_has_before_flying(flags: list[str], says: str, tmp_path: Path) -> None:
    from feelium.cli import main

    with pytest.raises(SystemExit, match=says):
        main(["calibrate", "flight", *([] if "--port" in flags else ["--sim"]), "--out", str(tmp_path / "out"), *flags])
    assert not any(tmp_path.iterdir())


def test_cli_refuses_an_out_it_cannot_write_and_a_port_that_does_not_open_without_a_traceback(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    from feelium.cli import main

    taken = tmp_path / "a-file"
    taken.write_text("")
    with pytest.raises(SystemExit, match="cannot write to --out"):
        main(["calibrate", "flight", "--sim", "--out", str(taken)])
    assert main(["calibrate", "flight", "--port", str(tmp_path / "no-such-port"), "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "the link to" in err and "no-such-port" in err and "Traceback" not in err
    assert not any((tmp_path / "out").iterdir())


def test_the_report_writes_a_value_that_is_not_a_number_as_null_so_strict_json_parsers_read_it() -> None:
    from feelium.lab.report import finite_or_null

    report = {"values": {"a": {"value": float("nan"), "stderr": float("inf")}}, "list": [1.0, -float("inf")], "n": 3}
    assert json.loads(json.dumps(finite_or_null(report), allow_nan=False)) == {
        "values": {"a": {"value": None, "stderr": None}}, "list": [1.0, None], "n": 3}
