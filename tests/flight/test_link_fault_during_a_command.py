"""A held command through a board stall or a dropped link, on plants the shipped config was not tuned to: no faster,
no later stop.

During a 3 s stall the board's watchdog stops the motors, the body floats to the ceiling (where the flow is
noisiest) and the held command, back on fresh telemetry, corrects with tiny pushes. One such window read the flow's
noise as a brake of the box's strongest and the speed cap doubled: on main at session 33, 7 of 128 held commands
through a stall (16 corners, 2 seeds, 2 stall windows, forward and backward) ran over 1.2 of the command, up to 1.49,
and 4 took over 1.5 s to stop after the release, up to 1.88 s (docs/flight-robustness.md, session 33).

After a dropped link the held command corrected against itself (the body read faster than the cap) on a side nothing
had confirmed: such a push escalated from the command's start, long past, so it was at once divided by a learned value
the outage's noisy windows had taught the box's weakest, and the motors swung from full reverse to full forward; the
brake assured the margin and the cap rose, and corner-mtdL ran to 1.445 of the command (session 33).
"""

from __future__ import annotations

import pytest

from feelium.daemon.config import Config
from feelium.lab.flight.plants import plant_set
from feelium.lab.flight.safety import GOALS, held_through_fault

CONFIG = Config().flight


@pytest.mark.parametrize("corner,seed", [("corner-MTdL", 1), ("corner-MtdL", 1)])
def test_a_held_forward_through_a_stall_keeps_the_speed_and_stop_goals(corner: str, seed: int) -> None:
    """Was 1.485 of the command (corner-MTdL) and a 1.88 s stop after the release (corner-MtdL); the release ends
    the command at once, so its goal is an explicit stop's (1.0 s)."""
    plant = next(p for p in plant_set(16) if p.name == corner)
    figures = held_through_fault(CONFIG, plant, "forward", "stall", at_s=3.0, long_s=3.0, seed=seed)
    assert figures["speed_peak_fraction"] <= GOALS["speed_peak_fraction"]
    assert figures["stop_s"] <= GOALS["stop_s"]


def test_a_held_forward_through_a_dropped_link_keeps_the_speed_goal() -> None:
    """Was 1.445 of the command: an untaught push escalates from when it took its sign, not from the command's start."""
    plant = next(p for p in plant_set(16) if p.name == "corner-mtdL")
    figures = held_through_fault(CONFIG, plant, "forward", "drop", at_s=0.5, long_s=3.0, seed=1)
    assert figures["speed_peak_fraction"] <= GOALS["speed_peak_fraction"]
    assert figures["stop_s"] <= GOALS["stop_s"]


@pytest.mark.parametrize("plant_name,kind,at_s,seed,lag_s", [
    ("corner-mTDl", "stall", 0.5, 1, 0.0), ("random-2026-2", "stall", 3.0, 2, 0.0), ("corner-MtdL", "drop", 0.5, 2, 0.0),
    ("random-2026-27", "stall", 3.0, 1, 0.0), ("corner-mTdl", "drop", 0.5, 3, 0.03), ("corner-mTDl", "stall", 3.0, 5, 0.03)])
def test_after_a_fault_the_body_back_inside_its_altitude_limits_stays_within_the_goal(plant_name: str, kind: str,
                                                                                      at_s: float, seed: int,
                                                                                      lag_s: float) -> None:
    """The rise during the fault and the climb it carries on with are the board's (its watchdog stops the motors: the
    contract's); from the body's return inside the limits it is the controller's, judged as the safety flight's
    altitude goal (``safety.back_inside_limits``). Held on the ceiling limit itself, the descent's bounces went 0.29,
    0.26 and 0.18 m over it on the first three; the hold now aims a margin inside (``loops.recovery_target``). The
    last three went 0.13, 0.40 and 0.24 m over it with the margin: windows against the room's ceiling had taught the
    down side several times its answer; now they teach nothing (``AltitudeObserver.learn``; both session 36). A
    descending body's figure reads just under 0.1 m by construction (its return is where it crossed 0.1 m): a miss is a
    climb back after that."""
    plant = next(p for p in plant_set(50) if p.name == plant_name)
    figures = held_through_fault(CONFIG, plant, "forward", kind, at_s=at_s, long_s=3.0, seed=seed, lag_s=lag_s)
    assert figures["returned_s"] < 6.0
    assert figures["excursion_after_return_m"] <= GOALS["altitude_excursion_m"]

