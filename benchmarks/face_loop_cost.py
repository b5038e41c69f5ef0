"""CPU per second of a looping avatar on the projector's side: ``ProjectorService.update_face`` fed the board bench's
face video (24 JPEGs at 12 fps, ``feelium.lab.daemon.headset``), as ``feelium bench board`` plays it.

    PYTHONPATH=$PWD python3 benchmarks/face_loop_cost.py [--seconds 20] [--rounds 3] [--json FILE]

Each showing of a face frame is decoded and fitted to the canvas on the loop's pool unless it is kept decoded
(``[projector] face_cache_mb``, :mod:`feelium.projector.facecache`, since session 17). The clock is simulated (no
sleeping), the daemon's malloc settings are applied (fresh arrays above 128 KB are mmaps whose pages fault in), and
the figure is the process CPU time (the pool thread's and the loop's) per second of playback, the first two seconds
(the first time round the loop) included; rounds are medians. For an A/B run it from the older tree with
``PYTHONPATH`` pointing there.
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time
from pathlib import Path

import cv2

from feelium.daemon.config import Config
from feelium.daemon.memory import tune_malloc
from feelium.hub import Hub
from feelium.lab.daemon.headset import FACE_FPS, _face_video
from feelium.projector.display import SimDisplay
from feelium.projector.service import ProjectorService
from feelium.skin.projector_map import ProjectorMap, load_or_default
from feelium.lab.report import print_and_save


async def _play(jpegs: list[bytes], seconds: float, calibration: ProjectorMap) -> float:
    """Process CPU ms per second of playback."""
    now = [0.0]
    hub = Hub(clock=lambda: now[0])
    service = ProjectorService(Config().projector, Config().interactions, hub, SimDisplay(), calibration)
    start = time.process_time()
    for k in range(int(seconds * FACE_FPS)):
        now[0] = k / FACE_FPS
        hub.face.publish(now[0], jpegs[k % len(jpegs)])
        await service.update_face()
    return 1000.0 * (time.process_time() - start) / seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    config = Config()
    tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)
    cv2.setNumThreads(2)
    jpegs = [field[2] for field in _face_video()._fields]
    # The daemon's stand-in map (no calibration file): only the renderer's canvas size matters to the faces.
    calibration = load_or_default(Path("no-calibration.npz"), (config.projector.width, config.projector.height), None)
    runs = [asyncio.run(_play(jpegs, args.seconds, calibration)) for _ in range(args.rounds)]
    report = {"frames": len(jpegs), "fps": FACE_FPS, "seconds": args.seconds, "cpu_ms_per_s": round(statistics.median(runs), 2),
              "runs": [round(r, 2) for r in runs]}
    print_and_save(report, args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
