"""The numeric share of each thread's CPU by sampling (Linux ``perf``): the split behind the projection, measured.

:mod:`feelium.lab.daemon.numeric` finds the share with a profile hook, which sees only the numpy and OpenCV calls
that are Python function calls: numpy's operators (``a + b``) raise no profile event, so its share is a lower
bound (touch 0.32, where this module reads 0.5). A sampling profiler needs no such guess. ``perf record`` samples
the process a few hundred times a second on the CPU clock; each sample falls in one shared object, and a sample in
numpy's or OpenCV's native code (or the BLAS they call) is numeric work, projected at 6x. Every other sample
counts as Python-level, at 10x: the interpreter, but also the C library (``memcpy`` for numpy or for bytes
alike: the leaf sample cannot tell), the kernel (system calls: on the Pi the Wi-Fi driver's, the serial port's)
and the other extension modules. So the share is still not an upper bound, only a nearer one.

Samples are grouped by thread name (the kernel's 15 bytes of it, set by :mod:`feelium.priority`): the dedicated
threads by their service, the loop's pool as one group (the pool's jobs cannot be told apart by a sample), the
event loop's thread apart (projected at 10x whole regardless), and the threads Python did not start (OpenCV's
worker pool) as ``other threads``.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
from collections import Counter
from pathlib import Path

from feelium.lab.daemon.attribution import OTHER_THREADS, POOL_PREFIX, THREAD_SERVICES

SAMPLE_HZ = 499  # not a multiple of any service's rate
NUMERIC_OBJECTS = ("_multiarray_umath", "_umath_linalg", "cv2", "openblas", "libgomp", "_pocketfft", "_simd")
KERNEL_NAME_BYTES = 15


def perf_usable() -> bool:
    """Whether ``perf record`` can sample this process here (installed and permitted by perf_event_paranoid)."""
    if shutil.which("perf") is None:
        return False
    with tempfile.TemporaryDirectory() as scratch:
        trial = subprocess.run(
            ["perf", "record", "-q", "-F", str(SAMPLE_HZ), "-e", "cpu-clock", "-o", str(Path(scratch) / "t"), "--", "true"],
            capture_output=True, timeout=30,
        )
    return trial.returncode == 0


def is_numeric_object(path: str) -> bool:
    """Whether a sample in this shared object is numpy's or OpenCV's native code (or a library they call)."""
    name = Path(path.strip("()")).name
    return any(part in name for part in NUMERIC_OBJECTS)


def group_of(comm: str, tid: int, pid: int) -> tuple[str, str]:
    """The (service, kind) a thread's samples count for, from its kernel name: kind ``thread`` for a dedicated
    thread, ``pool`` for the loop's pool, ``loop`` for the event loop's thread."""
    if tid == pid:
        return "MainThread", "loop"
    if comm.startswith(POOL_PREFIX[:KERNEL_NAME_BYTES]):
        return POOL_PREFIX, "pool"
    for prefix, service in THREAD_SERVICES.items():
        if comm.startswith(prefix[:KERNEL_NAME_BYTES]):
            return service, "thread"
    return OTHER_THREADS, "thread"


def shares_from_script(lines: list[str], pid: int) -> tuple[dict[str, dict[str, float]], dict[str, int]]:
    """Numeric share per (service, kind) from ``perf script -F comm,tid,ip,dso`` lines, and the samples per group.

    A line reads ``COMM TID IP (DSO)``; the name may hold spaces, so the fields are taken from the right."""
    numeric: Counter[tuple[str, str]] = Counter()
    total: Counter[tuple[str, str]] = Counter()
    for line in lines:
        fields = line.split()
        if len(fields) < 4 or not fields[-3].isdigit():
            continue
        comm, tid, dso = " ".join(fields[:-3]), int(fields[-3]), fields[-1]
        group = group_of(comm, tid, pid)
        total[group] += 1
        numeric[group] += is_numeric_object(dso)
    shares: dict[str, dict[str, float]] = {}
    for (service, kind), count in total.items():
        if kind != "loop":
            shares.setdefault(service, {})[kind] = round(numeric[(service, kind)] / count, 3)
    return shares, {f"{service}/{kind}": count for (service, kind), count in sorted(total.items())}


def pooled_shares(shares: dict[str, dict[str, float]], charged: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """The shares as the projection reads them: the loop pool's one share given to every service with pool CPU
    in ``charged`` (its jobs cannot be told apart by a sample)."""
    out = {service: dict(kinds) for service, kinds in shares.items() if service != POOL_PREFIX}
    pool = shares.get(POOL_PREFIX, {}).get("pool")
    if pool is not None:
        for service, kinds in charged.items():
            if kinds.get("pool", 0.0) > 0.0:
                out.setdefault(service, {})["pool"] = pool
    return out


class PerfSampler:
    """Samples this process with ``perf record`` while ``counting`` (the profiled window of ``bench board``).

    Same interface as :class:`feelium.lab.daemon.numeric.NumericProfiler` (``install``, ``counting``,
    ``uninstall``), so the bench opens and closes the window the same way; nothing runs inside the process."""

    def __init__(self, directory: Path) -> None:
        self.path = directory / "perf.data"
        self._proc: subprocess.Popen[bytes] | None = None

    def install(self) -> None:
        """Nothing to install: perf samples from outside."""

    def uninstall(self) -> None:
        self.counting = False

    @property
    def counting(self) -> bool:
        return self._proc is not None

    @counting.setter
    def counting(self, on: bool) -> None:
        if on and self._proc is None:
            self._proc = subprocess.Popen(
                ["perf", "record", "-q", "-F", str(SAMPLE_HZ), "-e", "cpu-clock", "-p", str(os.getpid()), "-o", str(self.path)],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )
        elif not on and self._proc is not None:
            self._proc.send_signal(signal.SIGINT)  # perf writes its file and exits
            self._proc.wait(timeout=30)
            self._proc = None

    def shares(self) -> tuple[dict[str, dict[str, float]], dict[str, int]]:
        """Numeric share per service and kind over the window, and the samples each group had."""
        script = subprocess.run(
            ["perf", "script", "-i", str(self.path), "-F", "comm,tid,ip,dso"], capture_output=True, text=True, check=True, timeout=120,
        )
        return shares_from_script(script.stdout.splitlines(), os.getpid())
