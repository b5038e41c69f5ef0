"""The heavy weak corners' turns at flight seeds the suite's 50 plants do not fly (issue 13, point 1).

``test_random_plants.py`` flies seed 1, on which every corner's turns happened to have a large push of each
sign confirmed before they needed it. At seeds 2-6 a heavy weak corner's right turn often found none: normalised
by the box's strongest yaw effectiveness (20 times the plant's answer) it reached 0.06-0.18 of the commanded rate,
too little ever to confirm one, and the left turn's brake was as weak: its lapse took 1.68-1.94 s (goal 1.5). The
yaw axis now counts on the other sign's confirmed value (``Effectiveness(mirrored=True)``; docs/flight-robustness.md,
session 20). Each flight is about 3 s of CPU.
"""

from __future__ import annotations

import pytest

from feelium.daemon.config import Config
from feelium.lab.flight.plants import corner_plants, describe
from feelium.lab.flight.safety import GOALS, safety_flight

CORNERS = {plant.name: plant for plant in corner_plants()}


@pytest.mark.parametrize(("name", "seed"), [("corner-MtDl", 2), ("corner-Mtdl", 3), ("corner-MtDl", 4)])
def test_a_heavy_weak_corner_turns_both_ways_and_stops_from_each_turn_in_time(name: str, seed: int) -> None:
    result = safety_flight(Config().flight, CORNERS[name], seed=seed)
    context = f"{describe(CORNERS[name])} seed {seed}: {result.manoeuvres}"
    assert result.failures() == {}, context  # every goal (the lapse was 1.68 / 1.76 / 1.80 s)
    for turn in ("turn_right-stop", "turn_left-lapse"):
        assert result.manoeuvres[turn]["peak_fraction"] >= 0.4, context  # capped at 10 of 20 deg/s (was 0.07-0.18)


def test_corner_mtdl_at_seed_2_stops_from_its_left_turn_in_time_and_its_forward_stop_is_still_open() -> None:
    """The plant of the report: its turns are fixed; its forward `stop` still fails (a hover heading correction
    turning back at 3.04 deg/s when the observation ends, docs/flight-robustness.md, session 20)."""
    result = safety_flight(Config().flight, CORNERS["corner-MtDL"], seed=2)
    context = f"{describe(CORNERS['corner-MtDL'])}: {result.manoeuvres}"
    assert result.lapse_s <= GOALS["lapse_s"], context  # 1.76 s before
    assert result.manoeuvres["turn_right-stop"]["peak_fraction"] >= 0.4, context  # 0.074 before
    assert set(result.failures()) <= {"stop_s"}, context  # the forward stop is still open (inf), see the docs
