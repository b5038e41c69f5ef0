"""How much of each service's CPU is numpy/OpenCV work: the measured split behind the projection onto the Pi.

Issue 16 projects numeric work (numpy, OpenCV) at 6x and Python-level work at
10x onto a 1 GHz Cortex-A53. Which is which is measured, not guessed: during a
separate profiled window a profile hook on every thread Python starts times
each outermost call of an OpenCV function or a numpy builtin (a C function
whose owner is numpy: ``ndarray.sum``, ``np.add.reduce``, ``np.concatenate``)
with the thread's CPU clock, and charges it to the service the thread works
for (dedicated threads by name, the loop's pool by the job it runs, as
:mod:`feelium.lab.daemon.attribution` charges their total).

It under-counts on purpose, so the projection errs high: numpy's operators and
ufunc calls (``a + b``, ``np.maximum(a, b)``) raise no profile event and are
counted as Python-level work, and the hook's own cost inflates the Python
side. The event loop's thread is not profiled (it runs Python-level work:
projected at 10x whole). Threads Python did not start (OpenCV's worker pool)
run nothing but native numeric code. Where Linux ``perf`` is usable ``bench board`` samples the share instead
(:mod:`feelium.lab.daemon.perfsplit`), which needs no such lower bound.
"""

from __future__ import annotations

import threading
import time
import types
from collections import defaultdict
from typing import Any

import cv2

from feelium.lab.daemon.attribution import JOB_SERVICE, OTHER_THREADS, POOL_PREFIX, thread_service

NUMERIC_PACKAGES = ("numpy", "cv2")


def _opencv_functions() -> frozenset[int]:
    """The ids of OpenCV's functions: cv2's module functions carry no module name, so they are known by identity."""
    found: set[int] = set()
    for value in vars(cv2).values():
        if isinstance(value, types.BuiltinFunctionType):
            found.add(id(value))
        elif isinstance(value, types.ModuleType) and value.__name__.startswith("cv2."):
            found.update(id(v) for v in vars(value).values() if isinstance(v, types.BuiltinFunctionType))
    return frozenset(found)


_OPENCV = _opencv_functions()


def is_numeric(function: Any) -> bool:
    """Whether a C function is numpy's or OpenCV's (a builtin method counts by the type of the object it is bound to)."""
    if id(function) in _OPENCV:
        return True
    module = getattr(function, "__module__", None)
    if module is None:
        owner = getattr(function, "__self__", None)
        if isinstance(owner, types.ModuleType):
            module = owner.__name__
        elif owner is not None:
            module = type(owner).__module__
    return bool(module) and module.split(".")[0] in NUMERIC_PACKAGES


class NumericProfiler:
    """Numeric CPU seconds per (service, kind), kind ``thread`` or ``pool`` as in :func:`attribution.charge`.

    Install before the threads to be measured start (``threading.setprofile`` reaches new threads only);
    ``counting`` opens and closes the window.
    """

    def __init__(self) -> None:
        self.seconds: dict[tuple[str, str], float] = defaultdict(float)
        self.counting = False
        self._local = threading.local()
        self._lock = threading.Lock()

    def install(self) -> None:
        threading.setprofile(self._hook)

    def uninstall(self) -> None:
        threading.setprofile(None)  # type: ignore[arg-type]

    def _hook(self, _frame: Any, event: str, function: Any) -> None:
        if event == "c_call":
            local = self._local
            depth = getattr(local, "depth", 0)
            if depth:
                local.depth = depth + 1
            elif is_numeric(function):
                local.depth, local.start = 1, time.thread_time()
        elif event in ("c_return", "c_exception"):
            local = self._local
            depth = getattr(local, "depth", 0)
            if depth == 1:
                local.depth = 0
                if self.counting:
                    self._charge(time.thread_time() - local.start)
            elif depth:
                local.depth = depth - 1

    def _charge(self, seconds: float) -> None:
        name = threading.current_thread().name
        if name.startswith(POOL_PREFIX):
            key = (getattr(JOB_SERVICE, "name", None) or OTHER_THREADS, "pool")
        else:
            service = thread_service(name)
            if service in ("MainThread", OTHER_THREADS):
                return
            key = (service, "thread")
        with self._lock:
            self.seconds[key] += seconds


def numeric_shares(numeric: dict[tuple[str, str], float], charged: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """Per service and kind, the share of its CPU that was numeric (0..1), where the profiled window charged any."""
    shares: dict[str, dict[str, float]] = {}
    for (service, kind), seconds in numeric.items():
        total = charged.get(service, {}).get(kind, 0.0)
        if total > 0:
            shares.setdefault(service, {})[kind] = round(min(1.0, seconds / total), 3)
    return shares
