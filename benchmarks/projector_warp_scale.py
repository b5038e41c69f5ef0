"""CPU per projector warp at the projector's resolution and on the optics' coarse grid, full and partial changes.

    PYTHONPATH=$PWD python3 benchmarks/projector_warp_scale.py [--frames 300] [--json FILE]

The board bench's stand-in calibration (the canvas spans 806x605 projector pixels: 0.635 canvas pixel per
projector pixel, so the coarse grid is 2/3 of the projector's), a smooth random canvas alternating with another
(every tile changes: a face video frame) and, separately, a 40x40 canvas patch changing (an answer alone). Each
figure is the median over ``--frames`` warps of the process CPU time (OpenCV's worker threads included: the
remap and the resize run partly on them) and of the calling thread's alone, in ms; the two settings are run
interleaved, frame by frame, so machine load falls on both alike.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import cv2
import numpy as np

from feelium.daemon.config import Config
from feelium.daemon.memory import tune_malloc
from feelium.projector.renderer import Renderer
from feelium.skin.projector_map import load_or_default


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    config = Config()
    tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)
    size = (config.projector.width, config.projector.height)
    roi = tuple(config.rear_camera.roi) if config.rear_camera.roi else None
    calibration = load_or_default(Path("/nonexistent/calibration.npz"), size, roi)
    renderers = {
        name: Renderer(dataclasses.replace(config.projector, warp_resolution=name), calibration) for name in ("full", "optics")
    }
    rng = np.random.default_rng(5)
    ch, cw = config.projector.canvas_height, config.projector.canvas_width
    faces = [cv2.GaussianBlur(rng.integers(0, 256, (ch, cw, 3), np.uint8), (0, 0), 2) for _ in range(2)]
    results: dict[str, dict[str, float]] = {}
    for case in ("every tile", "a 40x40 patch"):
        costs: dict[str, list[tuple[float, float]]] = {name: [] for name in renderers}
        for i in range(args.frames):
            canvas = faces[i % 2].copy()
            if case != "every tile":
                canvas = faces[0].copy()
                canvas[200:240, 100 + i % 2 : 140 + i % 2] = 255
            for name, renderer in renderers.items():
                process, thread = time.process_time(), time.thread_time()
                frame = renderer.warp(canvas)
                costs[name].append((time.process_time() - process, time.thread_time() - thread))
                del frame
        for name, pairs in costs.items():
            cpu = np.array(pairs[10:]) * 1e3
            results[f"{case}, {name}"] = {
                "process_ms": round(float(np.median(cpu[:, 0])), 3),
                "thread_ms": round(float(np.median(cpu[:, 1])), 3),
                "scale": "/".join(map(str, renderers[name].warp_scale)),
            }
            print(f"{case:>14}, {name:>6}: {results[f'{case}, {name}']}", flush=True)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump({"opencv_threads": cv2.getNumThreads(), "results": results}, handle, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
