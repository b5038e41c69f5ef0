"""``feelium bench flight --plants N``: the safety goals across randomised plants, median and worst case.

Each plant (``plants.py``: the box's 16 corners first, then random ones) flies
the whole safety flight (``safety.py``) twice in the same run: with the
config as shipped (``plant_uncertainty`` 2: the loops learn the plant and
count only on what they measured) and with the model trusted
(``plant_uncertainty`` 1: what the controller did before it learned, every
force from the config's mass and thrust). The worst plant is what a user
meets on a blimp nobody tuned; it decides.
"""

from __future__ import annotations

import statistics
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from typing import Any

from feelium.flight.config import FlightConfig
from feelium.lab.flight.plants import Plant, describe, plant_set
from feelium.lab.flight.safety import GOALS, safety_flight

VARIANTS = {"learned": None, "model_trusted": 1.0}


def _fly(job: tuple[FlightConfig, Plant, bool]) -> dict[str, Any]:
    config, plant, flow = job
    result = safety_flight(config, plant, flow=flow)
    return {"plant": plant.name, "figures": result.figures(), "failures": result.failures(), "manoeuvres": result.manoeuvres}


def _summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for goal, limit in GOALS.items():
        values = [row["figures"][goal] for row in rows]
        worst = max(rows, key=lambda row: row["figures"][goal])
        out[goal] = {"goal": limit, "median": statistics.median(values), "worst": max(values), "worst_plant": worst["plant"],
                     "plants_missing_goal": sum(1 for v in values if not v <= limit)}
    out["plants_meeting_every_goal"] = sum(1 for row in rows if not row["failures"])
    return out


def run_plant_bench(config: FlightConfig, count: int, seed: int = 2026, workers: int = 1, flow: bool = True) -> dict[str, Any]:
    """Every plant under every variant; per goal the median, the worst and which plant it was."""
    plants = plant_set(count, seed)
    report: dict[str, Any] = {"plants": count, "seed": seed, "optical_flow": flow,
                              "plant_list": {plant.name: describe(plant) for plant in plants}}
    for variant, uncertainty in VARIANTS.items():
        variant_config = config if uncertainty is None else replace(config, plant_uncertainty=uncertainty)
        jobs = [(variant_config, plant, flow) for plant in plants]
        if workers > 1:
            with ProcessPoolExecutor(workers) as pool:
                rows = list(pool.map(_fly, jobs))
        else:
            rows = [_fly(job) for job in jobs]
        report[variant] = {"plant_uncertainty": variant_config.plant_uncertainty, "summary": _summary(rows), "per_plant": rows}
    return report


def format_plant_table(report: dict[str, Any]) -> str:
    lines = [f"safety goals over {report['plants']} plants (seed {report['seed']}, optical flow {'on' if report['optical_flow'] else 'off'})",
             f"{'goal':28s} {'limit':>7s} | " + " | ".join(f"{v:>34s}" for v in VARIANTS)]
    lines.append(f"{'':28s} {'':>7s} | " + " | ".join(f"{'median':>9s} {'worst':>9s} {'missed':>6s} {'':>7s}" for _ in VARIANTS))
    for goal, limit in GOALS.items():
        cells = []
        for variant in VARIANTS:
            s = report[variant]["summary"][goal]
            cells.append(f"{s['median']:9.3f} {s['worst']:9.3f} {s['plants_missing_goal']:6d} {'':>7s}")
        lines.append(f"{goal:28s} {limit:7.2f} | " + " | ".join(cells))
    lines.append(f"{'plants meeting every goal':28s} {'':>7s} | " + " | ".join(
        f"{report[v]['summary']['plants_meeting_every_goal']:>34d}" for v in VARIANTS))
    return "\n".join(lines)
