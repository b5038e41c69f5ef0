"""The flight loop and the event loop over the daemon's first seconds: the largest gap between control cycles, and
the loop's lag, from the moment ``run_daemon`` is called (issue 16's start-up stall, docs/performance.md).

Runs the daemon in-process as ``feelium run`` does on a laptop (every part on its simulated backend, HTTP on an
ephemeral port, the daemon's own event loop kind) for ``--seconds``, and reports per run: when the flight loop
started and ran its first control cycle (until then nothing commands the motors), the largest gap between two
cycles after that (and when), the loop's lag p50/p99/max (a 10 ms sleeper's oversleep, the build included), and
what the event loop ran that took longer than ``--slow-ms`` (asyncio's loop only: ``--loop asyncio``, its debug
mode names the callback). ``PYTHONPATH=OTHER_CHECKOUT`` measures another version of the daemon. Run it several times, and under load (``--burn N`` starts
N busy-looping processes for the run), e.g.::

    .venv/bin/python benchmarks/startup_gaps.py --runs 5 --seconds 10
    .venv/bin/python benchmarks/startup_gaps.py --runs 5 --seconds 10 --burn 2
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import logging
import multiprocessing
import os
import statistics
import time
from typing import Any

from feelium.daemon.config import Config
from feelium.daemon.eventloop import new_event_loop
from feelium.daemon.runner import run_daemon, with_overrides
from feelium.daemon.sdnotify import Notifier
from feelium.flight.service import FlightService

LAG_PROBE_S = 0.01


def _burn() -> None:
    """A busy loop: another program wanting a whole core."""
    while True:
        pass


def _config(seconds: float) -> Config:
    config = with_overrides(Config(), sim=True)
    return dataclasses.replace(
        config,
        http=dataclasses.replace(config.http, port=0, token="x" * 32, token_file=""),
        daemon=dataclasses.replace(config.daemon, status_interval_s=max(60.0, 2 * seconds)),
    )


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


async def _one_run(seconds: float) -> dict[str, Any]:
    cycles: list[float] = []  # time.monotonic() of every control cycle's publication
    lags_ms: list[float] = []
    started: list[float] = []  # when the flight service's run() began: its first gap counts from there
    original, original_run = FlightService._publish, FlightService.run

    def publish(self: FlightService, out: Any) -> None:
        cycles.append(time.monotonic())
        original(self, out)

    async def run(self: FlightService) -> None:
        started.append(time.monotonic())
        await original_run(self)

    FlightService._publish = publish  # type: ignore[method-assign]
    FlightService.run = run  # type: ignore[method-assign]
    stop = asyncio.Event()

    async def lag_probe() -> None:
        while not stop.is_set():
            due = time.monotonic() + LAG_PROBE_S
            await asyncio.sleep(LAG_PROBE_S)
            lags_ms.append(1000.0 * max(0.0, time.monotonic() - due))

    async def stopper() -> None:
        await asyncio.sleep(seconds)
        stop.set()

    t0 = time.monotonic()
    cpu0 = time.process_time()
    probe = asyncio.create_task(lag_probe())
    timer = asyncio.create_task(stopper())
    await asyncio.sleep(0)  # the probe is sleeping before the daemon builds: a synchronous build shows as lag
    try:
        await run_daemon(_config(seconds), stop=stop, notifier=Notifier({}), on_pi=False)
    finally:
        FlightService._publish, FlightService.run = original, original_run  # type: ignore[method-assign]
        stop.set()
        await probe
        timer.cancel()
    gaps = [(b - a, a - t0) for a, b in zip(cycles, cycles[1:])]  # once flying; before: first_cycle_s
    worst = max(gaps, default=(float("nan"), float("nan")))
    return {
        "flight_started_s": round(started[0] - t0, 3) if started else None,
        "first_cycle_s": round(cycles[0] - t0, 3) if cycles else None,
        "cycles": len(cycles),
        "max_gap_ms": round(1000 * worst[0], 1),
        "max_gap_at_s": round(worst[1], 2),
        "gaps_over_100ms": sum(1 for g, _ in gaps if g > 0.1),
        "lag_p50_ms": round(_percentile(lags_ms, 0.5), 2),
        "lag_p99_ms": round(_percentile(lags_ms, 0.99), 2),
        "lag_max_ms": round(max(lags_ms, default=float("nan")), 1),
        "process_cpu_s": round(time.process_time() - cpu0, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--burn", type=int, default=0, help="busy-looping processes running alongside")
    parser.add_argument("--loop", choices=("auto", "uvloop", "asyncio"), default="auto")
    parser.add_argument("--slow-ms", type=float, default=0.0, help="asyncio only: log callbacks longer than this")
    parser.add_argument("--json", default="")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(relativeCreated)8.0f %(levelname)s %(name)s: %(message)s")
    burners = [multiprocessing.Process(target=_burn, daemon=True) for _ in range(args.burn)]
    for p in burners:
        p.start()
    results = []
    try:
        for _ in range(args.runs):
            loop, kind = new_event_loop(args.loop)
            if args.slow_ms > 0:
                loop.set_debug(True)
                loop.slow_callback_duration = args.slow_ms / 1000.0
                logging.getLogger("asyncio").setLevel(logging.WARNING)
            try:
                result = {"loop": kind, **loop.run_until_complete(_one_run(args.seconds))}
            finally:
                loop.close()
            print(json.dumps(result), flush=True)
            results.append(result)
    finally:
        for p in burners:
            p.kill()
    summary = {
        "load_1min": round(os.getloadavg()[0], 2),
        "burn": args.burn,
        "first_cycle_s_worst": max(r["first_cycle_s"] for r in results),
        "max_gap_ms_median": statistics.median(r["max_gap_ms"] for r in results),
        "max_gap_ms_worst": max(r["max_gap_ms"] for r in results),
        "lag_p99_ms_median": statistics.median(r["lag_p99_ms"] for r in results),
        "lag_max_ms_worst": max(r["lag_max_ms"] for r in results),
        "first_cycle_s_median": statistics.median(r["first_cycle_s"] for r in results),
    }
    print(json.dumps(summary))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"runs": results, "summary": summary}, f, indent=1)


if __name__ == "__main__":
    main()
