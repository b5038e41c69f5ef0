"""Blimps the controller was never tuned to: seeded random plants across the box of unknowns.

The controller's config describes the paper's blimp. A real one differs in
everything that cannot be measured with a ruler, by up to a factor of two
either way (``docs/flight-robustness.md``): per-axis mass with added mass,
yaw inertia, linear and quadratic drag, thrust per command and its reverse
ratio, the motor lag (40-150 ms) and a deadband (up to 60 us around 1500).
The motor geometry is what the contract documents, and the net buoyancy is
within 25 % of the config (it is weighed, and the altitude loop learns the
rest). The box's corners matter most, so the first plants of a set are
corners (every combination of the four properties that decide stopping and
overshoot: mass, thrust, drag, lag), the rest are random inside the box.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np

from feelium.flight.blimp_model import BlimpParams, DraftParams, MotorParams

FACTOR = 2.0  # every unmeasurable parameter within [1/FACTOR, FACTOR] of the nominal
LAG_S = (0.04, 0.15)
DEADBAND_MAX = 0.12  # 60 us of the 500 us half range
BUOYANCY_SPREAD = 0.25
MILD_DRAFTS = DraftParams(horizontal_m_s=0.075, vertical_m_s=0.06, yaw_torque_nm=0.001, correlation_s=2.0)
# The vertical pair must be able to push the net buoyancy down with this margin, or no controller can
# hold altitude: such a plant is outside the box (it is a lighter-than-specified motor, not an unknown).
VERTICAL_MARGIN = 1.3


@dataclass(frozen=True)
class Plant:
    """One randomised blimp and how it was drawn (for reports)."""

    name: str
    blimp: BlimpParams
    factors: dict[str, float]


def _draw(unit: dict[str, float], name: str) -> Plant:
    """A plant from unit coordinates in [0, 1] per dimension (0 and 1 are the box's faces)."""
    nominal = BlimpParams()

    def scale(key: str) -> float:
        return FACTOR ** (2.0 * unit[key] - 1.0)

    factors = {key: scale(key) for key in ("mass", "heave_mass", "sway_mass", "yaw_inertia", "drag", "linear_drag", "yaw_drag", "thrust", "vertical_thrust")}
    factors["h_reverse"] = min(1.0, nominal.horizontal_motor.reverse_ratio * scale("h_reverse"))
    factors["v_reverse"] = min(1.0, nominal.vertical_motor.reverse_ratio * scale("v_reverse"))
    factors["lag_s"] = LAG_S[0] + (LAG_S[1] - LAG_S[0]) * unit["lag"]
    factors["deadband"] = DEADBAND_MAX * unit["deadband"]
    factors["buoyancy"] = 1.0 + BUOYANCY_SPREAD * (2.0 * unit["buoyancy"] - 1.0)

    net_n = nominal.net_buoyancy_n * factors["buoyancy"]
    # What one vertical motor gives at the controller's largest command (0.9), through the deadband.
    at_max = ((0.9 - factors["deadband"]) / (1.0 - factors["deadband"])) ** 2
    vertical_thrust = max(nominal.vertical_motor.max_thrust_n * factors["vertical_thrust"], VERTICAL_MARGIN * net_n / (2 * at_max))
    factors["vertical_thrust"] = vertical_thrust / nominal.vertical_motor.max_thrust_n
    lift = nominal.body_mass_kg + net_n / 9.81
    blimp = replace(
        nominal,
        lift_kg=lift,
        surge_mass_factor=factors["mass"],
        heave_mass_factor=factors["heave_mass"],
        sway_mass_factor=factors["sway_mass"],
        yaw_inertia_kg_m2=nominal.yaw_inertia_kg_m2 * factors["yaw_inertia"],
        drag_coefficient=nominal.drag_coefficient * factors["drag"],
        linear_drag_n_per_m_s=nominal.linear_drag_n_per_m_s * factors["linear_drag"],
        yaw_quadratic_drag=nominal.yaw_quadratic_drag * factors["yaw_drag"],
        yaw_linear_drag=nominal.yaw_linear_drag * factors["yaw_drag"],
        horizontal_motor=MotorParams(
            max_thrust_n=nominal.horizontal_motor.max_thrust_n * factors["thrust"],
            reverse_ratio=factors["h_reverse"],
            time_constant_s=factors["lag_s"],
            deadband=factors["deadband"],
        ),
        vertical_motor=MotorParams(
            max_thrust_n=vertical_thrust,
            reverse_ratio=factors["v_reverse"],
            time_constant_s=factors["lag_s"],
            deadband=factors["deadband"],
        ),
    )
    return Plant(name, blimp, {k: round(v, 4) for k, v in factors.items()})


DIMENSIONS = ("mass", "heave_mass", "sway_mass", "yaw_inertia", "drag", "linear_drag", "yaw_drag", "thrust",
              "vertical_thrust", "h_reverse", "v_reverse", "lag", "deadband", "buoyancy")


def corner_plants() -> list[Plant]:
    """The 16 corners of (mass and inertia, thrust, drag, lag), with the largest deadband and the weakest reverse.

    Heavy, weak, slippery and slow is the hardest stop; light, strong, slippery and slow the worst overshoot.
    """
    plants = []
    for mass, thrust, drag, lag in itertools.product((0.0, 1.0), repeat=4):
        unit = {key: 0.5 for key in DIMENSIONS}
        unit.update(mass=mass, heave_mass=mass, sway_mass=mass, yaw_inertia=mass, thrust=thrust, vertical_thrust=thrust,
                    drag=drag, linear_drag=drag, yaw_drag=drag, lag=lag, deadband=1.0, h_reverse=0.0, v_reverse=0.0)
        label = "".join(("M" if mass else "m", "T" if thrust else "t", "D" if drag else "d", "L" if lag else "l"))
        plants.append(_draw(unit, f"corner-{label}"))
    return plants


def random_plants(count: int, seed: int) -> list[Plant]:
    """``count`` plants drawn uniformly in the box's unit coordinates (log-uniform factors)."""
    rng = np.random.default_rng(seed)
    return [_draw({key: float(rng.random()) for key in DIMENSIONS}, f"random-{seed}-{i}") for i in range(count)]


def plant_set(count: int, seed: int = 2026) -> list[Plant]:
    """The corners first, then random plants, ``count`` in all."""
    corners = corner_plants()
    return corners[:count] + random_plants(max(0, count - len(corners)), seed)


def describe(plant: Plant) -> str:
    """One line a test failure or a bench row can print."""
    return plant.name + " " + " ".join(f"{k}={v:g}" for k, v in plant.factors.items() if not math.isnan(v))
