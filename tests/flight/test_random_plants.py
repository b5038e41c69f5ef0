"""Fifty blimps nobody tuned the controller to (the box's 16 corners, then random ones), judged by the worst.

Each flies the whole safety flight (``feelium/lab/flight/safety.py``) with the
config as shipped. Every goal is asserted on every plant (the hover reversals
too since session 10: the last three plants over it, 0.60-0.67/s, now fly at
0.20-0.47/s); the full table is ``feelium bench flight --plants 50``
(``docs/flight-robustness.md``).
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

import pytest

from feelium.daemon.config import Config
from feelium.lab.flight.plants import describe, plant_set
from feelium.lab.flight.safety import GOALS, SafetyResult, safety_flight

PLANTS = plant_set(50)


def _fly(index: int) -> SafetyResult:
    return safety_flight(Config().flight, PLANTS[index])


@pytest.fixture(scope="module")
def flights(request: pytest.FixtureRequest) -> dict[int, SafetyResult]:
    """The selected plants' flights, flown on every core at once (independent and seeded: the same results as
    one after another; the 50 flights are a third of the suite's time on one core)."""
    wanted = sorted(
        item.callspec.params["index"]
        for item in request.session.items
        if item.module is request.module and hasattr(item, "callspec")
    )
    workers = max(1, min(len(os.sched_getaffinity(0)), 4, len(wanted)))
    if workers == 1:
        return {index: _fly(index) for index in wanted}
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        return dict(zip(wanted, pool.map(_fly, wanted)))


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(PLANTS)), ids=[plant.name for plant in PLANTS])
def test_never_faster_or_turning_faster_than_commanded_stopped_in_time_inside_the_altitude_limits_and_quiet(
    index: int, flights: dict[int, SafetyResult]
) -> None:
    result = flights[index]
    context = describe(PLANTS[index])
    assert result.speed_peak_fraction <= GOALS["speed_peak_fraction"], context
    assert result.turn_peak_fraction <= GOALS["turn_peak_fraction"], context
    assert result.stop_s <= GOALS["stop_s"], context
    assert result.lapse_s <= GOALS["lapse_s"], context
    assert result.altitude_excursion_m <= GOALS["altitude_excursion_m"], context
    assert result.hover_reversals_per_s <= GOALS["hover_reversals_per_s"], context
