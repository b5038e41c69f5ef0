"""What OpenCV's thread pool policy costs: the projector's renderer and the touch pipeline, each paced at 30 fps in
its own thread as in the daemon, for SECONDS; process CPU ms per second (``os.times``) and the render's wall time.

    python benchmarks/opencv_pool_cost.py [--seconds 15]
    OPENCV_FOR_THREADS_NUM=1 python benchmarks/opencv_pool_cost.py                      # one OpenCV thread
    OPENCV_THREAD_POOL_ACTIVE_WAIT_WORKER=2000 OPENCV_THREAD_POOL_ACTIVE_WAIT_MAIN=10000 \\
        python benchmarks/opencv_pool_cost.py                                           # OpenCV's spinning default

The package sets no active wait unless the environment says otherwise (feelium/__init__.py); run the three
back to back and compare (docs/performance.md).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import threading
import time

import cv2
import numpy as np

from feelium.daemon.config import Config
from feelium.daemon.memory import tune_malloc
from feelium.lab.daemon.preloaded import rear_frames
from feelium.lab.projector.stream import FACE_FPS, FACE_FRAMES, answers_at, face_video
from feelium.projector.renderer import Renderer
from feelium.sim.projection import FisheyeWarp
from feelium.skin.projector_map import ProjectorMap
from feelium.touch.pipeline import TouchPipeline

FPS = 30.0


def _calibration(config: Config) -> ProjectorMap:
    """The simulated fisheye calibration `feelium bench projector` uses."""
    px, py = FisheyeWarp().truth_map(640, 480)
    roi = (64, 48, 512, 384)
    outside = np.ones(px.shape, bool)
    outside[roi[1] : roi[1] + roi[3], roi[0] : roi[0] + roi[2]] = False
    px[outside] = np.nan
    py[outside] = np.nan
    return ProjectorMap((640, 480), (config.projector.width, config.projector.height), roi, px, py, source="sim")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0)
    args = parser.parse_args()
    config = Config()
    tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)
    renderer = Renderer(config.projector, _calibration(config))
    faces = face_video(renderer, 1)
    size = (config.touch.width, config.touch.height)
    frames, roi = rear_frames(config.sim, size, FPS, 6.0)
    pipeline = TouchPipeline(config.touch, size, roi)
    start = time.monotonic()
    stop = start + args.seconds

    def touch() -> None:
        i = 0
        while time.monotonic() < stop:
            pipeline.process(i / FPS, frames[i % len(frames)])
            i += 1
            time.sleep(max(0.0, start + i / FPS - time.monotonic()))

    worker = threading.Thread(target=touch, name="touch")
    before = os.times()
    worker.start()
    walls = []
    i = 0
    while time.monotonic() < stop:
        now = i / FPS
        began = time.perf_counter()
        frame = renderer.render(now, faces[int(now * FACE_FPS) % FACE_FRAMES], answers_at(now, 1))
        del frame  # as the daemon's consumers do: the pool may reuse it
        walls.append(1000.0 * (time.perf_counter() - began))
        i += 1
        time.sleep(max(0.0, start + i / FPS - time.monotonic()))
    worker.join()
    after = os.times()
    elapsed = time.monotonic() - start
    print(json.dumps({
        "opencv_threads": cv2.getNumThreads(),
        "environment": {k: v for k, v in os.environ.items() if k.startswith("OPENCV_")},
        "process_cpu_ms_per_s": round(1000.0 * (after.user + after.system - before.user - before.system) / elapsed, 1),
        "render_wall_ms_median": round(statistics.median(walls), 2),
        "render_wall_ms_p90": round(float(np.percentile(walls, 90)), 2),
        "render_fps": round(i / elapsed, 2),
        "load_1min": round(os.getloadavg()[0], 1),
    }))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
