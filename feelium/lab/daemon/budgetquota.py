"""``feelium bench quota``: do the rates hold inside a CPU quota equal to the projected budget? (issue 16, point 3)

The quota is derived in the same command, from the projection's own factor measured minutes before: the day's
numeric split (a factor of 8.05-8.28 in sessions 25-29) rather than one carried over by hand. The factor is per core
of the measuring host, as the projection is, so a slower host makes both the projection and this check harsher
together. So the command

1. runs the board bench unconfined, with the numeric split, for the effective factor ``pi_cores / cores here``
   (every service's measured mix of 6x and 10x work), in a child process so that the confined run's memory is its own;
2. sets the group's quota to ``budget / factor`` of a core, plus what the simulated devices measured in the daemon's
   process use (the blimp runs the real sensors; the projection leaves them out, so the quota must too);
3. runs the board bench again inside that quota and judges the rates, misses and loop lag there.

What a pass shows, and what it does not: that the daemon's total CPU fits the budget with every service at its rate.
The quota is harsher than the Pi for bursts (the Pi's four cores give every wake-up an idle core, where a quarter of
a core makes any wake-up in a period's spent part wait for the next period) and gentler for one thread's latency
(while quota is left, each thread runs at this host's single-core speed, about 8 times an A53's): a frame, a tick or
the loop's lag is measured at host speed. The event loop thread's own projection (it cannot use more than one Pi
core) is judged by the unconfined run, not here.

Where the machine is the Pi itself there is no factor: give ``--quota-us`` (200 % of a core is ``--quota-us 20000``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from feelium.daemon.config import Config, load_config
from feelium.lab.daemon.attribution import SIM_DEVICES
from feelium.lab.daemon.board import bench_board, format_table
from feelium.lab.daemon.projection import BUDGET
from feelium.lab.daemon.quota import quota_of, restore_quota, set_quota
from feelium.lab.report import emit_report

PERIOD_US = 10_000  # 10 ms: a frame's work spans several periods, so throttling delays, rather than skips, a frame
MIN_QUOTA_US = 1_000  # the kernel's floor for a CFS quota and its period
MAX_PERIOD_US = 1_000_000  # the kernel's ceiling for the period
# The budget lines a quota can break: what runs inside it, not what it is (pi_cores) or holds (memory).
QUOTA_CHECKS = ("every service >= 97 % of target", "every service < 1 % misses", "touch at 30 fps", "loop lag p99 <= 20 ms")

Bench = Callable[..., dict[str, Any]]


def quota_for_budget(unconfined: dict[str, Any], period_us: int = PERIOD_US) -> dict[str, Any]:
    """The quota, in microseconds per ``period_us``, that the projected budget stands for on this host.

    ``unconfined``: a board bench result with its numeric split. Its effective factor is ``pi_cores`` over the
    cores used here without the simulated devices (those are not projected); the quota is the budget over that
    factor, plus the simulated devices' measured share, which runs in the daemon's process here and not on the Pi.
    """
    sim_ms = unconfined["services"].get(SIM_DEVICES, {}).get("cpu_ms_per_s", 0.0)
    here_cores = (unconfined["process_cpu_ms_per_s"] - sim_ms) / 1000.0
    if not here_cores > 0 or not unconfined["pi_cores"] > 0:
        raise ValueError(f"the unconfined run measured no CPU ({here_cores} cores here, {unconfined['pi_cores']} projected)")
    factor = unconfined["pi_cores"] / here_cores
    fraction = BUDGET["pi_cores"] / factor + sim_ms / 1000.0
    quota_us = round(fraction * period_us)
    if quota_us < MIN_QUOTA_US:  # raising it would hand out more than the budget and still call it the budget
        raise ValueError(f"the budget is {quota_us} us per {period_us} us period, under the kernel's {MIN_QUOTA_US}: use a longer period")
    return {
        "budget_pi_cores": BUDGET["pi_cores"],
        "factor": round(factor, 3),
        "factor_source": unconfined["pi_factor"],
        "sim_devices_ms_per_s": sim_ms,
        "quota_us": quota_us,
        "period_us": period_us,
        "unconfined_pi_cores": unconfined["pi_cores"],
        "unconfined_budget": unconfined["budget"],
    }


def quota_verdict(confined: dict[str, Any]) -> dict[str, Any]:
    """The budget lines a quota can break, judged on the run inside it; ``holds`` when all are kept."""
    checks = {name: confined["budget"][name] for name in QUOTA_CHECKS}
    timed = {name: row for name, row in confined["services"].items() if row.get("target_hz")}
    short = sorted(
        name for name, row in timed.items()
        if row["rate_hz"] < BUDGET["rate_fraction"] * row["target_hz"] or row["miss_pct"] >= BUDGET["miss_pct"]
    )
    return {"checks": checks, "services_short": short, "holds": all(checks.values())}


def unconfined_in_child(config_path: str | None, minutes: float, numeric_split_s: float) -> dict[str, Any]:
    """The unconfined board bench with its numeric split, in a process of its own: the confined run that follows
    then starts in a process that holds nothing of it (its memory figures are its own)."""
    with tempfile.TemporaryDirectory(prefix="feelium-quota-") as scratch:
        out = Path(scratch) / "unconfined.json"
        command = [sys.executable, "-m", "feelium", "bench", "board", "--minutes", str(minutes),
                   "--numeric-split-seconds", str(numeric_split_s), "--json", str(out)]
        child = subprocess.Popen(command + (["--config", config_path] if config_path else []), stdout=subprocess.DEVNULL,
                                 start_new_session=True)  # a Ctrl-C reaches it through terminate(), so its cleanup runs
        try:
            code = child.wait()
        finally:
            if child.poll() is None:
                child.terminate()
                child.wait()
        if code != 0:
            raise RuntimeError(f"the unconfined board bench exited with {code}")
        return json.loads(out.read_text())


def bench_quota(
    config: Config,
    group: Path,
    minutes: float,
    *,
    unconfined: Callable[[], dict[str, Any]] | None = None,
    quota_us: int | None = None,
    period_us: int = PERIOD_US,
    bench: Bench = bench_board,
) -> dict[str, Any]:
    """Derive the quota from the ``unconfined`` run (unless ``quota_us`` is given), run the board bench inside
    ``group`` with it, judge. The group's previous quota is put back afterwards, whatever happens in between."""
    measured = None
    if quota_us is None:
        if unconfined is None:
            raise ValueError("give either the unconfined run or the quota")
        measured = unconfined()
        derived = quota_for_budget(measured, period_us)
    else:
        derived = {"quota_us": quota_us, "period_us": period_us, "given": True}
    before = quota_of(group)
    try:
        set_quota(group, derived["quota_us"], period_us)
        confined = bench(config, minutes, cgroup=group, numeric_split_s=0.0)
    finally:
        restore_quota(group, before)
    return {
        "quota": {**derived, "cgroup": str(group), "quota_before": before},
        "unconfined": measured,
        "confined": confined,
        "verdict": quota_verdict(confined),
    }


def format_quota(result: dict[str, Any]) -> str:
    quota = result["quota"]
    if quota.get("given"):
        how = "given"
    else:
        split = "" if quota["factor_source"] != 10.0 else "; no numeric split: every part at 10x"
        missed = [name for name, ok in quota["unconfined_budget"].items() if not ok]
        how = (
            f"{quota['budget_pi_cores']} Pi cores over the factor {quota['factor']} of an unconfined run just before, "
            f"which projected {quota['unconfined_pi_cores']} Pi cores{split} and missed "
            f"{', '.join(missed) if missed else 'no budget line'}; + {quota['sim_devices_ms_per_s']} ms/s of simulated devices"
        )
    verdict = result["verdict"]
    lines = [
        format_table(result["confined"]),
        f"quota {quota['quota_us']} us per {quota['period_us']} us ({how}) in {quota['cgroup']}; before: {quota['quota_before']}",
        "inside the quota: " + ", ".join(f"{name} {'ok' if ok else 'MISSED'}" for name, ok in verdict["checks"].items()),
    ]
    if verdict["services_short"]:
        lines.append("  short of rate or over the misses budget: " + ", ".join(verdict["services_short"]))
    return "\n".join(lines)


def _group(path: str) -> Path:
    """The cgroup to use, created when its parent is a CPU controller's hierarchy (needs root); refused before
    anything runs when the quota could not be set or would be shared (a directory this made is removed again)."""
    group = Path(path)
    made = not group.is_dir()
    if made:
        group.mkdir()
    try:
        if not (group / "cpu.max").exists() and not (group / "cpu.cfs_quota_us").exists():
            raise OSError(f"{group} has no cpu.max nor cpu.cfs_quota_us: not a cgroup with the cpu controller "
                          "(on cgroup v2 the parent's cgroup.subtree_control needs +cpu; docs/performance.md)")
        if (group / "cgroup.procs").read_text().strip():
            raise OSError(f"{group} already holds processes: they would share the quota with the daemon")
        if any(child.is_dir() for child in group.iterdir()):
            raise OSError(f"{group} has child groups: the daemon could not join it")
        restore_quota(group, quota_of(group))  # the same values back: a group this user may not write fails now
        if not os.access(group / "cgroup.procs", os.W_OK):
            raise OSError(f"{group / 'cgroup.procs'} is not writable by this user")
    except OSError:
        if made:
            group.rmdir()
        raise
    return group


def _interrupt_on_sigterm() -> None:
    """SIGTERM (systemd, kill) as a KeyboardInterrupt, so the group's old quota is put back on the way out."""
    def raise_interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, raise_interrupt)


def bench_quota_command(args: argparse.Namespace) -> int:
    import logging

    from feelium.daemon.journal import setup_logging

    setup_logging(logging.WARNING)
    for name in ("minutes", "calibrate_minutes"):
        if not 0 < getattr(args, name) < math.inf:
            print(f"feelium bench quota: --{name.replace('_', '-')} must be positive and finite", file=sys.stderr)
            return 2
    if not 0 <= args.numeric_split_seconds < math.inf:
        print("feelium bench quota: --numeric-split-seconds must be 0 or more, and finite", file=sys.stderr)
        return 2
    if not MIN_QUOTA_US <= args.period_us <= MAX_PERIOD_US:
        print(f"feelium bench quota: --period-us must be within {MIN_QUOTA_US}-{MAX_PERIOD_US} (the kernel's limits)", file=sys.stderr)
        return 2
    if args.quota_us is not None and args.quota_us < MIN_QUOTA_US:
        print(f"feelium bench quota: --quota-us must be at least {MIN_QUOTA_US} (the kernel's floor)", file=sys.stderr)
        return 2
    try:
        group = _group(args.cgroup)
    except OSError as exc:
        print(f"feelium bench quota: --cgroup {args.cgroup}: {exc}", file=sys.stderr)
        return 2
    config = load_config(args.config)
    _interrupt_on_sigterm()
    result = bench_quota(
        config, group, args.minutes, quota_us=args.quota_us, period_us=args.period_us,
        unconfined=lambda: unconfined_in_child(args.config, args.calibrate_minutes, args.numeric_split_seconds),
    )
    emit_report(format_quota(result), result, args.json)
    return 0 if result["verdict"]["holds"] else 1
