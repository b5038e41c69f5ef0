"""Thread CPU per frame of the touch pipeline alone, on the rear frames `feelium bench board` plays, with the daemon's
malloc settings (allocation costs what it costs in `feelium run`).

    python benchmarks/touch_frame_cost.py [--loops 3] [--projected] [--json FILE]

``--projected`` passes a predicted light and spread with every frame (seeded noise around the flat grey, changing
every 7 frames), the path the Pi runs with a projector calibration; the bench's frames hold no projection, so this
measures the cost, not the accuracy. The first loop warms up; the figure is the median of the later loops' means.
For an A/B, run it from a worktree of the older commit with ``PYTHONPATH`` pointing there, back to back.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from feelium.daemon.config import Config
from feelium.daemon.memory import tune_malloc
from feelium.lab.daemon.preloaded import rear_frames
from feelium.touch.pipeline import TouchPipeline
from feelium.lab.report import print_and_save


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loops", type=int, default=3, help="passes over the 6 s of frames (the first warms up)")
    parser.add_argument("--projected", action="store_true", help="with a projected light and spread per frame")
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    config = Config()
    tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)
    size = (config.touch.width, config.touch.height)
    frames, roi = rear_frames(config.sim, size, 30.0, 6.0)
    pipeline = TouchPipeline(config.touch, size, roi)
    rng = np.random.default_rng(3)
    lights = [np.clip(1.0 + 0.3 * rng.standard_normal(size[::-1]), 0.0, 3.0).astype(np.float32) for _ in range(4)]
    spreads = [np.abs(0.02 * rng.standard_normal(size[::-1])).astype(np.float32) for _ in range(4)]
    per_loop = []
    k = 0
    for _ in range(max(2, args.loops)):
        cpu = 0.0
        for i, frame in enumerate(frames):
            extra = {}
            if args.projected:
                extra = {"projected_light": lights[(i // 7) % 4], "projected_spread": spreads[(i // 7) % 4]}
            start = time.thread_time()
            pipeline.process(k / 30.0, frame, **extra)
            cpu += time.thread_time() - start
            k += 1
        per_loop.append(1000.0 * cpu / len(frames))
    report = {
        "projected": args.projected,
        "frames_per_loop": len(frames),
        "ms_per_frame_by_loop": [round(v, 3) for v in per_loop],
        "ms_per_frame": round(statistics.median(per_loop[1:]), 3),
    }
    print_and_save(report, args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
