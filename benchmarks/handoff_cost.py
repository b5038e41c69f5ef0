"""CPU per awaited hand-off to a worker thread: ``loop.run_in_executor`` against ``feelium.cameras.handoff.call_on``.

    python benchmarks/handoff_cost.py [--calls 3000] [--rounds 3]

Flight awaits one job of its serial thread every 50 Hz tick and the projector one render every frame; what such a
round trip costs the event loop's thread (the part that cannot spread over cores) and the process is what this
times, on asyncio's loop and on uvloop (the daemon's), with a job that does nothing. Rounds alternate the two ways
back to back; it prints the median of the rounds, microseconds per call.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor

from feelium.cameras.handoff import call_on


async def _round_trips(way: str, calls: int) -> tuple[float, float]:
    """(loop thread us, process us) per call of a no-op job on a one-thread executor."""
    loop = asyncio.get_running_loop()
    with ThreadPoolExecutor(1) as executor:
        await loop.run_in_executor(executor, int)  # the thread exists before the clock starts
        process0, thread0 = time.process_time(), time.thread_time()
        for i in range(calls):
            if way == "run_in_executor":
                await loop.run_in_executor(executor, int, i)
            else:
                await call_on(executor, int, i)
        process1, thread1 = time.process_time(), time.thread_time()
    return 1e6 * (thread1 - thread0) / calls, 1e6 * (process1 - process0) / calls


def _run(loop_kind: str, way: str, calls: int) -> tuple[float, float]:
    if loop_kind == "uvloop":
        import uvloop

        return uvloop.run(_round_trips(way, calls))
    return asyncio.run(_round_trips(way, calls))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    report: dict[str, dict[str, float]] = {}
    for loop_kind in ("asyncio", "uvloop"):
        runs: dict[str, list[tuple[float, float]]] = {"run_in_executor": [], "call_on": []}
        for _ in range(args.rounds):
            for way in runs:
                runs[way].append(_run(loop_kind, way, args.calls))
        for way, figures in runs.items():
            report[f"{loop_kind} {way}"] = {
                "loop_thread_us": round(statistics.median(f[0] for f in figures), 1),
                "process_us": round(statistics.median(f[1] for f in figures), 1),
            }
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
