"""Thread CPU per frame of the projector's share (:class:`feelium.touch.roomshare.ProjectorShare`) alone: ``learn``
on every frame (one in three with a hand in view: the short memory only) and the per-tile map (``coarse``, as a
candidate or health reads it), on a membrane lit by the probe with a lamp as bright as the projector.

    PYTHONPATH=$PWD python3 benchmarks/roomshare_cost.py [--width 320 --height 240] [--frames 300] [--runs 3]

One OpenCV thread, as the daemon's touch thread. Reports the median over frames (after 50 of warm-up) of each run,
and the median of the runs, in ms. The pipeline's own figure is ``share learn`` and ``share coarse`` in
``benchmarks/touch_compensated_cost.py --profile``; this one isolates the share for A/B runs of its arithmetic
(older trees: ``share_map`` is timed where ``coarse`` is missing). Nothing is asserted: speed claims live here, not
in tests.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import cv2
import numpy as np

from feelium.skin.probe import probe_light, probe_pattern
from feelium.touch.roomshare import ProjectorShare

FPS = 30.0
WARM_UP = 50


def run(width: int, height: int, frames: int, seed: int) -> dict[str, float]:
    """One pass: the median ms per frame of ``learn`` and of the map."""
    rng = np.random.default_rng(seed)
    pattern = probe_pattern(width, height, cell_px=32)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    r2 = ((xx - width / 2) / (width / 2)) ** 2 + ((yy - height / 2) / (height / 2)) ** 2
    a = (150.0 / (1.0 + 2.0 * r2)).astype(np.float32)  # the back-light's fall-off to the corners
    c = np.full(a.shape, float(a.mean()), np.float32)  # a lamp as bright as the projector on average
    usable = rng.random(a.shape) > 0.05
    share = ProjectorShare(tau_s=5.0)
    coarse = getattr(share, "coarse", share.share_map)
    learn, maps = [], []
    for i in range(frames):
        t = i / FPS
        light = probe_light(t, pattern)
        frame = (a * light + c + rng.normal(0.0, 2.0, a.shape)).astype(np.float32)
        start = time.thread_time()
        share.learn(t, frame, a + c, light, usable, hand_free=i % 3 != 0)
        middle = time.thread_time()
        coarse()
        end = time.thread_time()
        if i >= WARM_UP:
            learn.append(middle - start)
            maps.append(end - middle)
    return {"learn": 1000.0 * statistics.median(learn), "map": 1000.0 * statistics.median(maps)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    runs = [run(args.width, args.height, args.frames, seed) for seed in range(args.runs)]
    report = {key: round(statistics.median(r[key] for r in runs), 3) for key in ("learn", "map")}
    report["total"] = round(report["learn"] + report["map"], 3)
    report["runs"] = [{k: round(v, 3) for k, v in r.items()} for r in runs]
    print(json.dumps(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
