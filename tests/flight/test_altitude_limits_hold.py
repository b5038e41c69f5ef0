"""The altitude hold at the end of a stop, and outside the limits (issue 13, point 1; session 23).

Two defects, both traced on flights:
- a weak, heavy-drag blimp released under ``altitude_min`` believed its up push (never learned: the box's strongest)
  2.2 times the model, pushed a tenth of what it needed and sank 12 cm under the limit (corner-mtDl, flight seed 8:
  0.123 m; corner-mtDL at the same seed took the same path, 0.128 m, with the second change below alone). Outside the limits the push back inside now counts on the assured
  effectiveness, and a settling stop (damping only) does not wait there;
- a settling stop held the altitude's last estimate, one range-noisy cycle 1 cm low, and sank to it 2 s later at
  2.5 cm/s: the flight bench's released `up` on a fitted config "stopped" in 2.40 s (0.44 s before session 22; the
  body had stopped in 0.4 s both times). It now holds the altitude's recent mean.
"""

from __future__ import annotations

import dataclasses

import pytest

from feelium.daemon.config import Config
from feelium.flight.controller import FlightController
from feelium.flight.setpoint import HOLD, Setpoint
from feelium.lab.flight import scenarios
from feelium.lab.flight.plants import corner_plants
from feelium.lab.flight.safety import GOALS, safety_flight

CONFIG = Config().flight


def _hold_force(z: float, target: float, learned_up: float | None = None, setpoint: Setpoint = HOLD) -> float:
    """The vertical force a still hold at ``z`` asks for on its first cycle toward ``target``, with the up side's
    learned effectiveness ``learned_up`` (``None``: never learned, the box's strongest); ``setpoint``: what the
    headset holds (a held `down` keeps its reference at the floor)."""
    controller = FlightController(CONFIG)
    obs, loop = controller.altitude, controller.altitude_loop
    obs.z, obs.vz = z, 0.0
    loop.restart(target)
    if learned_up is not None:
        obs.effectiveness.values[1] = learned_up
    return loop.step(10.0, 1.0 / CONFIG.rate_hz, setpoint, obs, controller.thrust, 1.0, False)


def test_below_the_floor_the_push_up_counts_on_the_assured_effectiveness_whatever_was_learned() -> None:
    """1 cm under the floor (small enough not to reach a motor limit): the same force whether the up side is
    unlearned (the box's strongest, 4x) or learned at 1x or at the assured value; inside the limits the same error
    asks for less, divided by the learned value. Before, under the floor too."""
    floor = CONFIG.altitude_min_m
    assured = FlightController(CONFIG).altitude.effectiveness.assured(1.0)
    below = [_hold_force(floor - 0.01, floor, learned) for learned in (None, 1.0, assured)]
    assert below == pytest.approx([below[0]] * 3)
    inside = _hold_force(floor + 0.05, floor + 0.06)  # the same 1 cm error, inside the limits, unlearned
    lo, hi = FlightController(CONFIG).mixer.limits_up_n()
    assert inside < below[0] < hi
    assert _hold_force(floor + 0.05, floor + 0.06, assured) == pytest.approx(below[0])  # as if learned at the assured


def test_below_the_floor_in_a_held_down_the_push_up_counts_on_the_assured_effectiveness_too() -> None:
    """A `down` held into the floor: its reference stays at the floor and the body under it is pushed back up as by
    a hold. That push divided by the up side's value, which a climb had taught 3.72 (truth about 1), was a quarter of
    what it needed: the body sank on through the floor at 8 cm/s, 0.32 m under it (corner-mtDl, flight seed 32)."""
    floor = CONFIG.altitude_min_m
    down = Setpoint(climb_m_s=-CONFIG.climb_rate_m_s)
    assured = FlightController(CONFIG).altitude.effectiveness.assured(1.0)
    below = [_hold_force(floor - 0.01, floor, learned, down) for learned in (None, 3.72, 1.0, assured)]
    assert below == pytest.approx([below[0]] * 4)
    assert below[0] > _hold_force(floor + 0.01, floor, 3.72, down)  # inside the limits, divided by the value


@pytest.mark.slow
@pytest.mark.parametrize("name", ["corner-mtDL", "corner-mtDl"])
def test_a_weak_blimp_released_at_the_floor_stays_within_its_goal(name: str) -> None:
    """Flight seed 8: 0.047 / 0.123 m under the floor on main (0.128 / 0.031 with the rest mean alone); now 0.046 /
    0.073 m (goal 0.10)."""
    plant = {p.name: p for p in corner_plants()}[name]
    result = safety_flight(CONFIG, plant, seed=8)
    assert result.altitude_excursion_m <= GOALS["altitude_excursion_m"], result.figures()


def test_a_released_up_on_a_fitted_config_stays_stopped() -> None:
    """The bench's stop: below 10 % of the climb rate for the rest of the run. 2.40 s before (the sink to a noisy
    target); the body itself stops in about 0.45 s."""
    fitted = dataclasses.replace(CONFIG, plant_uncertainty=1.0)
    result = scenarios.motion(fitted, "up", seed=1)
    assert result.stop_s <= 0.6, result.stop_s
