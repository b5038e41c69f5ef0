"""The random plants of ``test_random_plants.py`` at flight seeds other than 1 (issue 13, point 1; session 27).

Flown first in session 27 (``benchmarks/flight_seed_sweep.py --plants 50 --only 16-49 --seeds 1-6``): 5 of 204 flights
missed a goal. Three sank to the floor in the first hover and stayed there, motors pushing down, for the rest of the
flight: far below its target the loop freezes the altitude disturbance (a partner holding the body down must not wind
it up), and the observer, its model's push brought forward over the range slope's age, held a climb rate of
+0.18 m/s with the rangefinder at 1 cm, so the loop saw a climb and never pushed harder. Two more left the altitude
band by 0.12 and 0.14 m (not traced: far below the target the same lagging climb rate is the likely cause). Frozen
like that, the climb rate is now the range slope (``AltitudeObserver``), and all five meet every goal
(docs/flight-robustness.md, session 27).
"""

from __future__ import annotations

import pytest

from feelium.daemon.config import Config
from feelium.lab.flight.plants import describe, plant_set
from feelium.lab.flight.safety import safety_flight

PLANTS = plant_set(50)
MISSED = [  # (plant index, flight seed): the goal it missed before session 27's change, with the figure
    (20, 4),  # sank to the floor: altitude 0.40 m, its stops never completed
    (28, 4),  # the same
    (32, 5),  # the same, and hover reversals 0.60 per second
    (42, 3),  # altitude 0.117 m
    (46, 5),  # altitude 0.143 m
]


@pytest.mark.slow
@pytest.mark.parametrize(("index", "seed"), MISSED, ids=[f"{PLANTS[index].name}-s{seed}" for index, seed in MISSED])
def test_a_random_plant_that_missed_a_goal_at_another_seed_now_meets_them_all(index: int, seed: int) -> None:
    result = safety_flight(Config().flight, PLANTS[index], seed=seed)
    assert result.failures() == {}, f"{describe(PLANTS[index])} seed {seed}: {result.manoeuvres}"
