"""The ``[daemon]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class DaemonConfig:
    """Process-wide settings: logging and supervision."""

    log_level: Literal["debug", "info", "warning", "error"] = setting("info", "Log level of the journald lines.")
    restart_initial_s: float = setting(
        0.5, "First delay before restarting a crashed service; doubles on each crash in a row.", min=0.01, max=60.0
    )
    restart_max_s: float = setting(30.0, "Longest delay between restarts of a crashing service.", min=0.01, max=600.0)
    healthy_after_s: float = setting(
        30.0, "A service that ran this long before crashing starts its backoff afresh.", min=0.0, max=3600.0
    )
    give_up_after: int = setting(
        0, "Consecutive crashes after which a service is left failed; 0 = keep restarting.", min=0, max=10000
    )
    stop_timeout_s: float = setting(
        0.4, "Time each service gets for stop() at shutdown before it is cancelled.", min=0.01, max=5.0
    )
    shutdown_budget_s: float = setting(
        1.6, "Whole shutdown budget (stops, then cancels); systemd and tests expect exit within 2 s.", min=0.1, max=30.0
    )
    status_interval_s: float = setting(
        10.0, "How often a one-line status goes to the log and to systemd (STATUS=).", min=0.5, max=3600.0
    )
    malloc_arenas: int = setting(
        2, "glibc malloc arenas for the whole process (fewer = less resident memory); 0 = glibc's default.", min=0, max=64
    )
    malloc_mmap_threshold_kb: int = setting(
        128,
        "Allocations from this size (KB) are mmap'd and returned to the system when freed, so frame buffers do not "
        "fragment the heap; 0 = glibc's self-raising default.",
        min=0,
        max=32768,
    )
