"""How busy the horizontal motors are while the body moves: the mean tick-to-tick change of motors 1 and 2.

A loop that steers on a noisier speed passes that noise to the motors (wear, sound) without reversing them, which
the hover reversal goal does not count. This flies ``safety_flight`` on the box's 16 corners at the given flight
seeds, each with the config ``calibrate flight`` fitted on it (cached by ``flight_seed_sweep.py --calibrated
--cache DIR``), and prints the mean of ``|m[k+1] - m[k]|`` over the ticks where the body moves faster than 5 cm/s,
and over the whole flight (docs/calibrate-flight.md, session 26).

    PYTHONPATH=. .venv/bin/python benchmarks/flight_motor_activity.py --seeds 5,14 --cache DIR
"""

from __future__ import annotations

import argparse
import pickle
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

MOVING_M_S = 0.05


def _activity(job: tuple[int, int, str]) -> tuple[float, float]:
    import feelium.lab.flight.safety as safety
    import feelium.lab.flight.simulation as simulation
    from feelium.lab.flight.plants import corner_plants

    index, seed, cache = job
    flights: list[simulation.SimFlight] = []
    original = simulation.SimFlight.__init__

    def keep(self: simulation.SimFlight, *args: object, **kwargs: object) -> None:
        original(self, *args, **kwargs)  # type: ignore[arg-type]
        flights.append(self)

    simulation.SimFlight.__init__ = keep  # type: ignore[method-assign]
    with (Path(cache) / f"{index}-{seed}.pickle").open("rb") as f:
        config = pickle.load(f)
    safety.safety_flight(config, corner_plants()[index], seed=seed)
    log = flights[-1].log
    motors = np.stack([np.asarray(log["m1"]), np.asarray(log["m2"])], axis=1)
    change = np.abs(np.diff(motors, axis=0)).mean(axis=1)
    moving = np.abs(np.asarray(log["u"]))[1:] > MOVING_M_S
    return float(change[moving].mean()), float(change.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="5,14", help="flight seeds, e.g. 5,14")
    parser.add_argument("--cache", required=True, help="the fitted configs, {index}-{seed}.pickle (flight_seed_sweep.py)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    jobs = [(index, int(seed), args.cache) for seed in args.seeds.split(",") for index in range(16)]
    with ProcessPoolExecutor(args.workers) as pool:
        results = np.array(list(pool.map(_activity, jobs)))
    print(f"{len(jobs)} flights: mean |motor change| a tick while moving {results[:, 0].mean():.4f}, "
          f"over the whole flight {results[:, 1].mean():.4f}")


if __name__ == "__main__":
    main()
