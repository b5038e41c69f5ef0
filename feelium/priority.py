"""Flight comes first when the CPU runs short: the bulk work runs in threads the kernel serves last.

One process does everything, so the operating system cannot tell flight from
pixels unless each thread says which it is. The event loop's thread (flight
control, the headset's `stop`, every HTTP reply) and the flight serial thread
keep the process's priority; the threads that only move pixels (the touch
pipeline and the camera readers, the loop's shared pool: projector rendering,
JPEG encoding, thermal reads) run ``background_nice`` steps nicer. On a board
with cores to spare nothing changes; when the work outgrows the CPU (four A53
cores, or a CPU quota) the kernel's fair scheduler gives the nicer threads a
smaller share, so touch and the projector drop frames before flight misses a
control period. Raising one's own nice needs no privilege; where the system
refuses (not Linux, a sandbox), the daemon runs on at one priority and says so
once in the log.

Linux keeps a nice value per thread (``setpriority`` on a thread id), and a
thread inherits its creator's, so each pool lowers its own threads as they
start (:func:`lower_current_thread` as the executor's initializer). Each such
thread also gives the kernel its Python name, so ``top -H`` and ``ps -L`` on the
board show which thread spends the CPU (``touch-pipeline_``, ``flight-serial_``).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import threading

log = logging.getLogger(__name__)

PR_SET_NAME = 15  # from linux/prctl.h; the kernel keeps 15 bytes of a thread's name

_background_nice = 0
_refused = threading.Event()


def set_background_nice(steps: int) -> None:
    """How much nicer than the process the bulk-work threads started from now on run (0: as nice as the rest)."""
    global _background_nice
    _background_nice = max(0, int(steps))


def background_nice() -> int:
    return _background_nice


def name_current_thread() -> None:
    """Give the kernel the calling thread's Python name (an executor initializer; a no-op off Linux)."""
    name = ctypes.util.find_library("c")
    try:
        ctypes.CDLL(name).prctl(PR_SET_NAME, threading.current_thread().name.encode()[:15], 0, 0, 0)
    except (OSError, AttributeError, TypeError):
        pass  # no glibc or no prctl: the thread keeps the process's name


def lower_current_thread() -> None:
    """Make the calling thread ``background_nice`` steps nicer than the process (an executor initializer)."""
    name_current_thread()
    steps = _background_nice
    if steps == 0:
        return
    try:
        base = os.getpriority(os.PRIO_PROCESS, os.getpid())
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), min(19, base + steps))
    except (AttributeError, OSError) as exc:
        if not _refused.is_set():
            _refused.set()
            log.warning("bulk-work threads run at the flight loop's priority: the system refused a nicer one (%s)", exc)


def thread_nice(native_id: int) -> int:
    """The nice value of one of this process's threads (for health and tests)."""
    return os.getpriority(os.PRIO_PROCESS, native_id)
