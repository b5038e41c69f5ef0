"""Keeping the daemon's resident memory within a 512 MB board's budget.

Two glibc malloc habits cost a frame-churning process tens of MB for nothing:

- each thread that allocates gets its own arena and keeps freed memory there;
  capping the arenas (``M_ARENA_MAX``, as ``MALLOC_ARENA_MAX`` does) stops that;
- blocks above the mmap threshold are mmap'd and handed back to the kernel on
  free, but glibc raises that threshold each time such a block is freed (up to
  32 MB), after which frame-sized arrays land on the heap and fragment it.
  Fixing the threshold (``M_MMAP_THRESHOLD``) keeps frames mmap'd.

Measured with ``feelium bench daemon`` (see docs/daemon.md for the numbers).
Both must be set before the worker threads start.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
from collections.abc import Callable

log = logging.getLogger(__name__)

M_MMAP_THRESHOLD = -3  # from glibc's malloc.h
M_ARENA_MAX = -8


def _mallopt() -> ctypes._CFuncPtr | None:
    name = ctypes.util.find_library("c")
    if not name:
        return None
    try:
        mallopt = ctypes.CDLL(name).mallopt
    except (OSError, AttributeError):
        return None
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return mallopt


def _malloc_trim() -> ctypes._CFuncPtr | None:
    name = ctypes.util.find_library("c")
    if not name:
        return None
    try:
        trim = ctypes.CDLL(name).malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


class FreeMemoryReturner:
    """Hands the free pages inside glibc's heaps back to the kernel (``malloc_trim(0)``) every ``interval_s``.

    glibc gives back only the top of a heap by itself; the holes that the frame-rate churn of blocks under
    the mmap threshold (a 320x240 grey image is 75 KB) leaves inside stay resident. In ``feelium bench
    board`` each trim handed back 1.3-2.2 MB for 0.2-0.4 ms; the holes fill again within the second, so
    trimming every second moves the steady figure by ~0.4 MB (docs/performance.md, *Latest: resident memory
    under 150 MB*): small, and free. A no-op where there is no glibc.
    """

    def __init__(self, interval_s: float, trim: Callable[[int], int] | None = None) -> None:
        self.interval_s = interval_s
        self._trim = (trim or _malloc_trim()) if interval_s > 0 else None
        self._due = 0.0
        self.calls = 0

    def maybe(self, now: float) -> None:
        """Trim if ``interval_s`` has passed since the last trim (``now``: any monotonic clock)."""
        if self._trim is None or now < self._due:
            return
        self._due = now + self.interval_s
        self._trim(0)
        self.calls += 1


def tune_malloc(arenas: int, mmap_threshold_kb: int) -> dict[str, int]:
    """Cap glibc's arenas and fix its mmap threshold (0 leaves either at glibc's default).

    Returns what was applied; empty where there is no glibc (musl, macOS).
    """
    mallopt = _mallopt()
    applied: dict[str, int] = {}
    if mallopt is None:
        return applied
    for key, option, value in (
        ("malloc_arenas", M_ARENA_MAX, arenas),
        ("malloc_mmap_threshold_kb", M_MMAP_THRESHOLD, mmap_threshold_kb * 1024),
    ):
        if value <= 0:
            continue
        if mallopt(option, value) == 1:
            applied[key] = value if option == M_ARENA_MAX else value // 1024
        else:
            log.debug("mallopt(%d, %d) refused", option, value)
    return applied
