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


def set_quota(group: Path, quota_us: int, period_us: int) -> str:
    """Give ``group`` a quota of ``quota_us`` CPU microseconds every ``period_us``; returns the quota it had,
    as :func:`quota_of` states it, for :func:`restore_quota`. Either write may be refused (for instance when the
    parent's quota is lower): then the old values are put back before the error goes on, so a half-set group is
    never left behind."""
    before = quota_of(group)
    try:
        _write(group, str(quota_us), str(period_us))
    except OSError:
        restore_quota(group, before)
        raise
    return before


def restore_quota(group: Path, before: str) -> None:
    """Put back a quota :func:`set_quota` replaced (``max`` or ``-1``: none)."""
    quota, period = before.split()
    _write(group, quota, period)


def _write(group: Path, quota: str, period: str) -> None:
    """v2: both in one ``cpu.max``; v1: the period, then the quota."""
    if (group / "cpu.max").exists():
        (group / "cpu.max").write_text(f"{quota} {period}\n")
    else:
        (group / "cpu.cfs_period_us").write_text(f"{period}\n")
        (group / "cpu.cfs_quota_us").write_text(f"{quota}\n")
