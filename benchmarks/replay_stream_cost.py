"""What replaying a recording's projector stream costs the daemon's touch path (`feelium run --replay`, docs/touch.md,
*`run --replay` with the recording's projector stream*).

    PYTHONPATH=. python3 benchmarks/replay_stream_cost.py DATASET [--repeats 2]

Runs the daemon in-process with the touch service alone on a realtime replay of DATASET (recordings with their
projector stream and map beside them, e.g. `feelium simulate condition faceon --variants face`), and on a copy
without the stream files, interleaved ``--repeats`` times, and prints per run: camera frames processed and dropped,
the pipeline step's wall ms per frame (health's ``ms_per_frame``, the prediction included), the process's CPU ms
per processed frame (camera decoding included) and whether the light was compensated.
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from feelium.daemon.assembly import build_touch
from feelium.daemon.config import Config
from feelium.daemon.runner import run_daemon
from feelium.daemon.sdnotify import Notifier
from feelium.hub import Hub

STREAM_FILES = ("projector.mkv", "projector_ts.txt")


def _config(path: Path) -> Config:
    base = Config()
    rear = dataclasses.replace(base.rear_camera, backend="replay", replay_path=str(path), replay_realtime=True, replay_loop=False)
    return dataclasses.replace(base, rear_camera=rear)


async def _replay(path: Path) -> dict[str, Any]:
    """The daemon with touch alone until the replay ends; health's figures and the process CPU it took."""
    hub, stop, holder = Hub(), asyncio.Event(), {}
    start = resource.getrusage(resource.RUSAGE_SELF)

    async def watch() -> None:
        while "s" not in holder or holder["s"].records["touch"].state != "finished":
            await asyncio.sleep(0.05)
        stop.set()

    watcher = asyncio.create_task(watch())
    await run_daemon(
        _config(path), stop=stop, hub=hub, builders=(("touch", build_touch),), notifier=Notifier({}), on_pi=False,
        on_started=lambda h, s: holder.setdefault("s", s),
    )  # fmt: skip
    await watcher
    end = resource.getrusage(resource.RUSAGE_SELF)
    touch = hub.health()["services"]["touch"]
    cpu_s = (end.ru_utime + end.ru_stime) - (start.ru_utime + start.ru_stime)
    return {
        "frames": touch["frames"],
        "dropped": touch["dropped_frames"],
        "step_ms": touch["ms_per_frame"],
        "process_cpu_ms_per_frame": round(1e3 * cpu_s / max(touch["frames"], 1), 1),
        "compensated": touch["projection_compensation"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dataset", help="recordings with their projector stream and the map beside them")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        blind = Path(scratch) / "without-stream"
        shutil.copytree(args.dataset, blind)
        for name in STREAM_FILES:
            for path in blind.rglob(name):
                path.unlink()
        print(f"load average {', '.join(f'{x:.2f}' for x in os.getloadavg())}, {time.strftime('%H:%M:%S')}")
        for _ in range(args.repeats):
            for label, path in (("with the stream", Path(args.dataset)), ("without", blind)):
                print(label, asyncio.run(_replay(path)), flush=True)


if __name__ == "__main__":
    main()
