"""The shipped config's safety flight on the box's 16 corners at several flight seeds: which flights miss a goal.

``feelium bench flight --plants 16 --seed S`` flies each plant twice (shipped and model-trusted) and reports
one seed; this sweeps the shipped config alone over seeds and prints one JSON line per flight, then a summary
per seed (the table of docs/flight-robustness.md, sessions 20-21). Issue 13 judges by the worst plant, and
seed 1 alone (the one ``tests/flight/test_random_plants.py`` flies) hid 14 of 96 failing flights.

    .venv/bin/python benchmarks/flight_seed_sweep.py --seeds 1-6 --workers 2 > sweep.jsonl

About 2-3 s of CPU per flight: 96 flights in about 3-4 min on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from feelium.daemon.config import Config
from feelium.lab.flight.plants import plant_set
from feelium.lab.flight.safety import safety_flight

CORNERS = 16


def _fly(job: tuple[int, int]) -> dict[str, Any]:
    index, seed = job
    plant = plant_set(CORNERS)[index]
    result = safety_flight(Config().flight, plant, seed=seed)
    return {"plant": plant.name, "index": index, "seed": seed, "failures": result.failures(),
            "figures": {k: round(v, 3) for k, v in result.figures().items()}, "manoeuvres": result.manoeuvres}


def _seeds(text: str) -> list[int]:
    if "-" in text:
        first, last = text.split("-")
        return list(range(int(first), int(last) + 1))
    return [int(s) for s in text.split(",")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="1-6", help="flight seeds: 1-6 or 2,5")
    parser.add_argument("--only", default=None, help="corner indices, e.g. 8,9,10,11 (default: all 16)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    indices = [int(i) for i in args.only.split(",")] if args.only else list(range(CORNERS))
    jobs = [(index, seed) for seed in _seeds(args.seeds) for index in indices]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(_fly, jobs))
    for row in rows:
        print(json.dumps(row), flush=True)
    failing = [row for row in rows if row["failures"]]
    for seed in _seeds(args.seeds):
        misses = [f"{row['plant'].removeprefix('corner-')} "
                  + ", ".join(f"{k.split('_')[0]} {v:.2f}" for k, v in row["failures"].items())
                  for row in failing if row["seed"] == seed]
        print(f"seed {seed}: " + ("; ".join(misses) or "none"), file=sys.stderr)
    print(f"{len(failing)} of {len(rows)} flights miss a goal", file=sys.stderr)


if __name__ == "__main__":
    main()
