"""How well `feelium calibrate flight --sim` recovers each simulated plant's parameters: the recovery table of
docs/calibrate-flight.md, and the measurements behind its session-11 findings.

    PYTHONPATH=. python3 benchmarks/calibrate_recovery.py [--plants 0-19] [--no-drafts | --exact-sensors] [--yaw-tied]
        [--goals] [--seed S] [--workers N] [--json F]

Flies the calibration on plants of ``plant_set(20)`` (16 corners, then random ones; mild drafts unless
``--no-drafts``; the sensors' noise unless ``--exact-sensors``), one after another, and prints a JSON line per
plant (every parameter's relative error) then the table: plants within 10 %, median and worst error.
``--yaw-tied`` adds, per plant, the yaw torque per inertia's error as fitted and with the yaw's reverse torque
tied to surge's reverse ratio (the yaw steps alone cannot split them). ``--goals`` adds, per plant, what the
fitted config does on it: the axis uncertainties, the surge steps flown (level, seconds), the safety flight's
figures and whether it met every goal, and the tight goals (about 10 s more of CPU a plant). 8-25 s of CPU a plant.
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from typing import Any

import numpy as np

from feelium.daemon.config import Config
from feelium.flight import sysid
from feelium.flight.sim_board import SensorParams
from feelium.lab.flight.calibrate import Calibration, calibrate_sim, recovery_errors, tight_goals
from feelium.lab.flight.plants import Plant, plant_set
from feelium.lab.flight.safety import safety_flight

EXACT = replace(SensorParams(), range_noise_m=0.0, range_noise_fraction=0.0, range_dropout_probability=0.0,
                gyro_noise_dps=0.0, gyro_bias_dps=0.0, flow_noise_rad_s=0.0)


def yaw_tied_error(fits: sysid.AxisFits, sig: sysid.Signals, blimp: object) -> dict[str, float]:
    """The yaw torque per inertia's relative error, as fitted and with one push column ``(f1 - f2) - rh (r1 - r2)``."""
    truth = blimp.horizontal_motor.max_thrust_n * blimp.arm_m / blimp.yaw_inertia_kg_m2  # type: ignore[attr-defined]
    (f1, r1), (f2, r2) = sysid._pair_columns(sig, (0, 1), fits.lag_s, fits.horizontal_deadband, "yaw")
    surge = fits.surge
    rh = surge.estimate("reverse_thrust_per_mass").value / surge.estimate("thrust_per_mass").value
    r = sig.rate["yaw"]
    columns = {"torque": (f1 - f2) - rh * (r1 - r2), "linear": -r, "quadratic": -r * np.abs(r)}
    tied = sysid.least_squares(columns, sig.accel["yaw"], sig.trusted["yaw"], sig.sigma["yaw"])
    return {"fitted": round(float(fits.yaw.coef[0] / truth - 1.0), 4), "tied": round(float(tied.coef[0] / truth - 1.0), 4)}


def table(rows: list[dict[str, float]]) -> str:
    lines = ["| parameter | within 10 % | median error | worst error |", "|---|---|---|---|"]
    for name in rows[0]:
        errors = np.abs([row[name] for row in rows])
        lines.append(f"| {name} | {int((errors <= 0.10).sum())}/{errors.size} | {100 * np.median(errors):.0f} % | {100 * errors.max():.0f} % |")
    return "\n".join(lines)


def goals(calibration: Calibration, plant: Plant) -> dict[str, Any]:
    """What the fitted config does on ``plant``, and the surge steps that fitted it."""
    pilot, config = calibration.pilot, calibration.config
    safety = safety_flight(config, plant)
    return {"uncertainty": {axis: config.uncertainty(axis) for axis in ("heave", "surge", "yaw")},
            "surge_steps": [(pilot.script[i].level, round(end - start, 2)) for i, start, end in pilot.segments if pilot.script[i].axis == "surge"],
            "safety": {k: round(v, 3) for k, v in safety.figures().items()}, "every_safety_goal": not safety.failures(),
            "tight": {k: round(v, 4) for k, v in tight_goals(config, plant.blimp).items()}}


def one_plant(index: int, args: argparse.Namespace) -> dict[str, Any]:
    plant = plant_set(20)[index]
    calibration = calibrate_sim(Config().flight, plant.blimp, seed=args.seed, drafts=not args.no_drafts,
                                sensors=EXACT if args.exact_sensors else None)
    row: dict[str, Any] = {"plant": plant.name, "errors": {k: round(v, 4) for k, v in recovery_errors(calibration.fit, plant.blimp).items()}}
    if args.yaw_tied:
        row["yaw_torque_per_inertia"] = yaw_tied_error(*calibration.details, plant.blimp)
    if args.goals:
        row.update(goals(calibration, plant))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plants", default="0-19", help="indices of plant_set(20): 0-7 or 0,3,16")
    parser.add_argument("--no-drafts", action="store_true")
    parser.add_argument("--exact-sensors", action="store_true")
    parser.add_argument("--yaw-tied", action="store_true")
    parser.add_argument("--goals", action="store_true")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--json")
    args = parser.parse_args()
    if "-" in args.plants:
        first, last = (int(x) for x in args.plants.split("-"))
        indices = list(range(first, last + 1))
    else:
        indices = [int(x) for x in args.plants.split(",")]
    results = []
    with ProcessPoolExecutor(args.workers) as pool:
        for row in pool.map(one_plant, indices, [args] * len(indices)):
            print(json.dumps(row), flush=True)
            results.append(row)
    print(table([row["errors"] for row in results]))
    if args.json:
        with open(args.json, "w") as out:
            json.dump(results, out, indent=1)


if __name__ == "__main__":
    main()
