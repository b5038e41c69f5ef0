"""Fifty blimps nobody tuned the controller to (the box's 16 corners, then random ones), judged by the worst.

Each flies the whole safety flight (``feelium/lab/flight/safety.py``) with the
config as shipped. The goals asserted here are the ones every plant meets
(all but the hover reversals);
the full table, including the goals some plants still miss, is
``feelium bench flight --plants 50`` (``docs/flight-robustness.md``).
"""

from __future__ import annotations

import pytest

from feelium.daemon.config import Config
from feelium.lab.flight.plants import describe, plant_set
from feelium.lab.flight.safety import GOALS, SafetyResult, safety_flight

PLANTS = plant_set(50)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(PLANTS)), ids=[plant.name for plant in PLANTS])
def test_never_faster_or_turning_faster_than_commanded_stopped_in_time_and_inside_the_altitude_limits(index: int) -> None:
    result: SafetyResult = safety_flight(Config().flight, PLANTS[index])
    context = describe(PLANTS[index])
    assert result.speed_peak_fraction <= GOALS["speed_peak_fraction"], context
    assert result.turn_peak_fraction <= GOALS["turn_peak_fraction"], context
    assert result.stop_s <= GOALS["stop_s"], context
    assert result.lapse_s <= GOALS["lapse_s"], context
    assert result.altitude_excursion_m <= GOALS["altitude_excursion_m"], context
