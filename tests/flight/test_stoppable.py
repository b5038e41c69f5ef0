"""The fastest speed a plant can stop from within the stop goal (``stoppable.py``), and the cruise judged against it."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from feelium.flight.blimp_model import BlimpParams, MotorParams
from feelium.lab.flight.plant_bench import _tight_summary
from feelium.lab.flight.plants import plant_set
from feelium.lab.flight.stoppable import STOPPED_M_S, cruise_target, fastest_stoppable, stop_time

COMMAND_M_S, MAX_OUTPUT = 0.15, 0.9


def test_a_plant_with_strong_braking_is_judged_against_the_command() -> None:
    """The paper's blimp stops far faster than the commanded cruise needs: the target is the command."""
    target = cruise_target(COMMAND_M_S, BlimpParams(), MAX_OUTPUT)
    assert target["v_stop_m_s"] > 2 * COMMAND_M_S
    assert target["cruise_target_m_s"] == COMMAND_M_S


def test_halving_the_reverse_thrust_lowers_the_fastest_stoppable_speed() -> None:
    blimp = BlimpParams()
    weak = replace(blimp, horizontal_motor=replace(blimp.horizontal_motor, reverse_ratio=0.5 * blimp.horizontal_motor.reverse_ratio))
    strong_v, weak_v = fastest_stoppable(blimp, -MAX_OUTPUT), fastest_stoppable(weak, -MAX_OUTPUT)
    assert weak_v < 0.8 * strong_v


def test_without_lag_and_with_linear_drag_alone_it_is_the_analytic_stop() -> None:
    """m dv/dt = -F - c v from v0 reaches the threshold s at t = (m / c) ln((v0 + F/c) / (s + F/c)): setting
    t = 1 s gives v0 = (s + F/c) e^(c/m) - F/c."""
    motor = MotorParams(max_thrust_n=0.1, reverse_ratio=0.5, time_constant_s=1e-9, deadband=0.0)
    blimp = replace(BlimpParams(), drag_coefficient=0.0, linear_drag_n_per_m_s=0.05, horizontal_motor=motor)
    m, c = blimp.inertial_mass_kg * blimp.surge_mass_factor, blimp.linear_drag_n_per_m_s
    force = 2 * motor.max_thrust_n * motor.reverse_ratio  # both motors at full reverse
    analytic = (STOPPED_M_S + force / c) * math.exp(c / m) - force / c
    assert fastest_stoppable(blimp, -1.0, dt=1e-4) == pytest.approx(analytic, rel=2e-3)


def test_the_heavy_weak_corners_cannot_stop_the_command_and_the_bisection_finds_the_edge() -> None:
    """The four heavy, weak corners of the box (docs/calibrate-flight.md, session 17): 0.79-0.88 of the command."""
    heavy = [plant for plant in plant_set(12)[8:12]]
    assert [plant.name for plant in heavy] == ["corner-Mtdl", "corner-MtdL", "corner-MtDl", "corner-MtDL"]
    for plant in heavy:
        target = cruise_target(COMMAND_M_S, plant.blimp, MAX_OUTPUT)
        v = target["v_stop_m_s"]
        assert 0.75 * COMMAND_M_S < v == target["cruise_target_m_s"] < 0.9 * COMMAND_M_S, plant.name
        assert stop_time(plant.blimp, v, -MAX_OUTPUT) <= 1.0 < stop_time(plant.blimp, v + 0.002, -MAX_OUTPUT)


def test_the_bench_judges_the_cruise_goal_against_the_target_and_keeps_the_commanded_figure_beside_it() -> None:
    """A plant that cruises at its target below the command meets the goal against the target, misses it against
    the command; one that cruises slower than its target misses both."""
    def row(of_command: float, of_target: float) -> dict[str, dict[str, float]]:
        return {"tight": {"altitude_rms_m": 0.01, "heading_rms_deg": 0.1, "cruise_fraction": of_command,
                          "cruise_fraction_of_target": of_target}}

    summary = _tight_summary([row(0.80, 0.98), row(0.97, 0.97), row(0.40, 0.48)], "tight")
    assert summary["cruise_fraction_of_target"]["plants_missing_goal"] == 1
    assert summary["cruise_fraction_of_target"]["worst"] == 0.48
    assert summary["cruise_fraction"]["plants_missing_goal"] == 2


def test_the_bench_command_reads_plant_indices_as_lists_and_ranges() -> None:
    from feelium.cli.flight import _indices

    assert _indices("8-11", 16) == [8, 9, 10, 11] and _indices("0,3,8-9", 16) == [0, 3, 8, 9] and _indices(None, 16) is None
    for malformed, says in (("a-b", "plant indices like"), ("5", "outside the set"), ("15-16", "outside the set"),
                            ("3-1", "runs backwards")):
        with pytest.raises(SystemExit, match=says):
            _indices(malformed, 16 if malformed != "5" else 2)


@pytest.mark.parametrize("flags, says", [(["--workers", "2"], "--workers needs --plants"),
                                         (["--command-delay-ms", "5"], "--command-delay-ms needs --plants"),
                                         (["--json", "x.json"], "--json needs --plants"),
                                         (["--plants", "2", "--out", "elsewhere"], "--out is the nominal bench's"),
                                         (["--plants", "0"], "--plants must be 1 or more"),
                                         (["--workers", "0"], "--workers needs --plants"),
                                         (["--command-delay-ms", "0"], "--command-delay-ms needs --plants"),
                                         (["--plants", "2", "--workers", "0"], "--workers must be 1 or more"),
                                         (["--plants", "2", "--out", "bench-out/flight"], "--out is the nominal bench's")])
def test_the_bench_command_refuses_an_option_it_would_ignore(flags: list[str], says: str) -> None:
    """``--plants 0`` ran the nominal bench and ignored ``--json``; ``--workers`` without ``--plants`` was ignored (the
    session-32 reviews)."""
    from feelium.cli import main

    with pytest.raises(SystemExit, match=says):
        main(["bench", "flight", *flags])
