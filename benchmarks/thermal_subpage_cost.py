"""CPU per sub-page of the thermal service alone, as `feelium bench board` runs it: the I2C-level MLX90640
simulation (`sim`) behind the real transport, driver, decoder and presence detector, the service on an event loop
of its own, nothing else in the process.

    python benchmarks/thermal_subpage_cost.py [--seconds 20] [--json FILE]

Reports sub-pages read, polls (status reads: sub-pages, not ready, torn, stale), process CPU per sub-page (the
worker's and the loop's; the simulated device's share included, as in the bench), the loop thread's alone, and
the event loop's callbacks per sub-page (its wake-ups, asyncio's plumbing included).
For an A/B, run it from each worktree (``PYTHONPATH`` pointing there), back to back.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import sys
import time

from feelium.daemon.config import Config
from feelium.hub import Hub
from loop_callbacks import CallbackCount  # benchmarks/ is the script's own folder
from feelium.thermal.service import ThermalService, sim_driver
from feelium.lab.report import print_and_save


async def _run(seconds: float) -> dict[str, float]:
    config = Config()
    hub = Hub()
    service = ThermalService(config.thermal, hub, lambda: sim_driver(config.thermal, hub, config.sim.seed), "sim")
    task = asyncio.create_task(service.run())
    await asyncio.sleep(2.0)  # warm-up: calibration read, both sub-pages seen, imports done
    assert service.driver is not None
    counters = service.driver.counters

    def polls() -> int:
        return counters.subpages + counters.not_ready + counters.torn + counters.stale

    subpages0, polls0 = counters.subpages, polls()
    cpu0, loop0 = time.process_time(), time.thread_time()
    with CallbackCount() as count:
        await asyncio.sleep(seconds)
    cpu, loop = time.process_time() - cpu0, time.thread_time() - loop0
    subpages, polled = counters.subpages - subpages0, polls() - polls0
    await service.stop()
    task.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await task
    return {
        "subpages": subpages,
        "rate_hz": round(subpages / seconds, 2),
        "polls_per_subpage": round(polled / subpages, 2),
        "ms_per_subpage": round(1000.0 * cpu / subpages, 3),
        "loop_ms_per_subpage": round(1000.0 * loop / subpages, 3),
        "loop_callbacks_per_subpage": round(count.calls / subpages, 2),
        "cpu_ms_per_s": round(1000.0 * cpu / seconds, 2),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    report = asyncio.run(_run(args.seconds))
    print_and_save(report, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
