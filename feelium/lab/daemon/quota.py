"""Running the measured daemon under a CPU quota: the slow board's budget, enforced by the kernel.

The bench moves only its own process (the daemon) into an existing cgroup, after the board and
headset processes have started, so the quota binds the daemon and not the devices it talks to.
Creating the group needs root and differs between cgroup v1 and v2 (docs/performance.md has both).
"""

from __future__ import annotations

import os
from pathlib import Path


def quota_of(group: Path) -> str:
    """The group's quota as the kernel states it: v2 ``cpu.max`` ("20000 100000"), v1 quota and period in us."""
    if (group / "cpu.max").exists():
        return (group / "cpu.max").read_text().strip()
    quota = (group / "cpu.cfs_quota_us").read_text().strip()
    period = (group / "cpu.cfs_period_us").read_text().strip()
    return f"{quota} {period}"


def join(group: Path) -> str:
    """Move this process, all its threads, into ``group``; returns the quota that now applies."""
    (group / "cgroup.procs").write_text(f"{os.getpid()}\n")
    return quota_of(group)
