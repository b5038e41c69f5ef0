"""Keeping the daemon's resident memory within a 512 MB board's budget.

glibc gives each thread that allocates its own malloc arena and keeps freed
memory there, so a process whose worker threads churn numpy frames grows by
tens of MB for nothing (measured with `feelium bench daemon`: 181 MB with
the default, 140 MB with two arenas). Capping the arenas before the worker
threads start is the standard cure (the same as ``MALLOC_ARENA_MAX``).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging

log = logging.getLogger(__name__)

M_ARENA_MAX = -8  # from glibc's malloc.h


def limit_malloc_arenas(arenas: int) -> bool:
    """Cap glibc's malloc arenas (0 leaves the default); False where there is no glibc (musl, macOS)."""
    if arenas <= 0:
        return False
    name = ctypes.util.find_library("c")
    if not name:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    ok = mallopt(M_ARENA_MAX, arenas) == 1
    if not ok:
        log.debug("mallopt(M_ARENA_MAX, %d) refused", arenas)
    return ok
