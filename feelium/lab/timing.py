"""Per-call timing for the benchmarks, shared so every ``feelium bench`` reports the same statistics.

CPU time of the calling thread is the headline figure: it is what one core spends on the work and it stays
meaningful on a busy machine (CI, a Pi also running the camera), where wall time swings with the load. Wall
time is reported beside it so a reader can see the difference.
"""

from __future__ import annotations

import time
from typing import Any, Callable

import numpy as np


def time_calls(fn: Callable[[int], Any], calls: int) -> dict[str, float]:
    """Call ``fn(i)`` for i in 0..calls-1; median and p95 of thread CPU and wall time per call, in ms."""
    cpu, wall = [], []
    for i in range(calls):
        start_wall, start_cpu = time.perf_counter(), time.thread_time()
        fn(i)
        cpu.append((time.thread_time() - start_cpu) * 1000.0)
        wall.append((time.perf_counter() - start_wall) * 1000.0)
    c, w = np.asarray(cpu), np.asarray(wall)
    return {
        "median_ms": round(float(np.median(c)), 3),
        "p95_ms": round(float(np.percentile(c, 95)), 3),
        "wall_median_ms": round(float(np.median(w)), 3),
        "wall_p95_ms": round(float(np.percentile(w, 95)), 3),
    }
