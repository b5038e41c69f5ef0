"""How fast the measuring machine is, so projected Pi figures from different machines can be compared.

The projection onto the Pi (:mod:`feelium.lab.daemon.projection`) multiplies CPU measured *here* by a fixed
factor per kind of work. A faster host therefore projects a lighter Pi: the same code read 3.30 Pi cores on
session 16's host and about 2.0 on session 17's (an AMD EPYC VM). Two fixed workloads, one interpreted and one
numeric, timed before each run, say how much of a difference between two reports is the host's. They are
small (about 0.2 s in all) and run before the daemon starts, timed in process CPU (OpenCV may use its pool).
"""

from __future__ import annotations

import platform
import statistics
import time

import cv2
import numpy as np

REPEATS = 5


def cpu_model() -> str:
    """The CPU's model name as the kernel reports it (``/proc/cpuinfo``), else the platform's processor."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as cpuinfo:
            for line in cpuinfo:
                if line.lower().startswith(("model name", "hardware")):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _interpreted() -> None:
    """Python-level work of the daemon's kind: small objects, dict lookups, calls and float arithmetic."""
    state = {"x": 0.0, "v": 0.0}
    for i in range(20_000):
        error = 1.0 - state["x"]
        state["v"] += 0.01 * (2.0 * error - 0.5 * state["v"])
        state["x"] += 0.01 * state["v"] + (i & 3) * 1e-6


def _numeric(frame: np.ndarray, out: np.ndarray, mask: np.ndarray) -> None:
    """Numeric work of the touch pipeline's kind on a 640x480 float frame, ten times: a blur, a division, a count.

    Into preallocated buffers: the bench tunes glibc's malloc for the daemon (frame-sized blocks mmap'd), and a
    workload that allocated frame-sized temporaries read 3-4x slower after that than before it (2.4 against
    8-10 ms on one host, session 20), which is the allocator's cost, not the host's speed."""
    for _ in range(10):
        cv2.GaussianBlur(frame, (5, 5), 0.0, dst=out)
        np.add(out, 1e-3, out=out)
        np.divide(frame, out, out=out)
        np.greater(out, 1.05, out=mask)
        np.count_nonzero(mask)


def _median_ms(job: object, *args: object) -> float:
    times = []
    for _ in range(REPEATS):
        start = time.process_time()
        job(*args)  # type: ignore[operator]
        times.append(1000.0 * (time.process_time() - start))
    return round(statistics.median(times), 3)


def host_reference() -> dict[str, object]:
    """The host's CPU model and the median process-CPU milliseconds of each fixed workload."""
    frame = np.random.default_rng(0).random((480, 640), dtype=np.float32)
    out = np.empty_like(frame)
    mask = np.empty(frame.shape, dtype=bool)
    return {
        "cpu_model": cpu_model(),
        "python_ms": _median_ms(_interpreted),
        "numeric_ms": _median_ms(_numeric, frame, out, mask),
    }
