"""A held command cruises at the speed its stop was planned for, not a third over it.

The speed cap is the fastest speed the stop can brake from within its goal, on the braking the blimp has shown. On
the light and heavy corners of the box the onset left the body up to 38 % over it (0.086-0.094 m/s against 0.068 at
1.2 m at the end of a 12 s hold with no fault), and it stayed there: the correction against the command was a reverse push normalised by a side
no window had taught (the box's strongest), a few mN that the deadband ate, so the body coasted. Every stop then began
faster than planned; after a board stall, with late replies and the flow noisy under the ceiling, such stops took up
to 1.5 s (docs/flight-robustness.md, session 34). A correction against a held command now escalates while the
model-free, flow-led speed is measurably over the reference.
"""

from __future__ import annotations

import numpy as np
import pytest

from feelium.daemon.config import Config
from feelium.flight.setpoint import setpoint_for_motion
from feelium.flight.sim_board import BoardParams, board_with
from feelium.lab.flight.plants import MILD_DRAFTS, plant_set
from feelium.lab.flight.safety import GOALS, SETTLE_S, START_ALTITUDE_M
from feelium.lab.flight.simulation import SimFlight

CONFIG = Config().flight
HELD_S = 8.0
CRUISE_S = 3.0  # the last seconds of the hold, where the onset is long over


@pytest.mark.parametrize("corner", ["corner-mtdl", "corner-Mtdl", "corner-mTDL", "corner-MtDL"])
def test_a_held_forward_cruises_no_more_than_a_fifth_over_its_speed_cap(corner: str) -> None:
    """On main at session 34: corner-mtdl 1.31 and corner-MtDL 1.21 times the cap (corner-Mtdl 1.15, corner-mTDL 1.13);
    now 1.17, 1.14, 1.15 and 1.07. The fifth is the speed goal's own margin over a command; a body within twice the
    flow-led speed's noise of its reference is not corrected harder, which is what is left on these corners."""
    plant = next(p for p in plant_set(16) if p.name == corner)
    flight = SimFlight(CONFIG, board_with(BoardParams(blimp=plant.blimp, drafts=MILD_DRAFTS), z=START_ALTITUDE_M), seed=1)
    flight.run(SETTLE_S)
    flight.run(HELD_S, setpoint_for_motion("forward", CONFIG))
    t, u = flight.log["t"], flight.log["u"]
    cruise = float(np.mean(u[t > flight.t - CRUISE_S]))
    cap = flight.controller.surge_loop.speed_cap
    assert cruise <= GOALS["speed_peak_fraction"] * cap, f"{corner} cruised at {cruise:.3f} m/s against a cap of {cap:.3f}"


def test_a_correction_against_a_held_command_teaches_the_stop_nothing() -> None:
    """Escalated, the corrections against an overspeed pushed a few hundred mN, and their windows assured corner-MtdL's
    reverse side at 0.70 where its brakes showed 0.13-0.16: the cap rose to the command and the stop after a stall 3 s
    into the hold took 1.22 s. A correction marks no real push, as a hover correction does not."""
    plant = next(p for p in plant_set(16) if p.name == "corner-MtdL")
    flight = SimFlight(CONFIG, board_with(BoardParams(blimp=plant.blimp, drafts=MILD_DRAFTS), z=START_ALTITUDE_M), seed=1)
    flight.run(SETTLE_S)
    escalated = 0
    while flight.t < SETTLE_S + HELD_S:
        flight.step(setpoint_for_motion("forward", CONFIG))
        escalated += flight.controller.surge_loop.over_reference_s > 0.0 and flight.controller.surge_loop.correcting
    effectiveness = flight.controller.surge.effectiveness
    assert escalated > 0, "the hold never corrected an overspeed: the test flies nothing"
    assert effectiveness.real_push_t[0] is None
    assert effectiveness.assuring_samples[0] == 0
