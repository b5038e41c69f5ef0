"""``feelium bench soak``: the board bench run long, judged on what a long uptime breaks (issue 15).

A leak, a queue that only grows or a counter that slowly starves a service shows
only after many minutes; the figures are the board bench's (``board.py``) and
this module only states the long-uptime verdict beside them, so one run answers
both questions and nothing is measured twice.
"""

from __future__ import annotations

import argparse
from typing import Any

from feelium.daemon.config import load_config
from feelium.lab.daemon.board import bench_board, format_table
from feelium.lab.daemon.projection import BUDGET
from feelium.lab.report import emit_report

SOAK_LIMITS = {"rss_mb": 150.0, "rss_growth_mb": 5.0, "miss_pct": BUDGET["miss_pct"], "rate_fraction": BUDGET["rate_fraction"]}
# The growth is judged from this long a run on: its warm-up fifth is then 2 minutes, and a leak of the
# size that matters on the board (a few MB an hour) is out of the noise of the samples.
MIN_GROWTH_S = 600.0


def soak_verdict(result: dict[str, Any]) -> dict[str, Any]:
    """Each long-uptime goal and whether the run kept it; ``holds`` when all did.

    A run too short to tell a leak from warm-up (under ``MIN_GROWTH_S``, or no growth figure) does not pass."""
    growth = result["rss_growth_mb"] if result["seconds"] >= MIN_GROWTH_S else None
    timed = {name: row for name, row in result["services"].items() if row.get("target_hz")}
    short = sorted(
        name for name, row in timed.items()
        if row["rate_hz"] < SOAK_LIMITS["rate_fraction"] * row["target_hz"] or row["miss_pct"] >= SOAK_LIMITS["miss_pct"]
    )
    checks = {
        "RSS steady <= 150 MB": result["rss_mb"] <= SOAK_LIMITS["rss_mb"],
        f"growth after warm-up < 5 MB (judged from {MIN_GROWTH_S / 60:g} minutes on)": growth is not None
        and growth < SOAK_LIMITS["rss_growth_mb"],
        "no service short of its rate or over 1 % misses": not short,
    }
    return {"limits": SOAK_LIMITS, "checks": checks, "services_short": short, "holds": all(checks.values())}


def format_verdict(verdict: dict[str, Any]) -> str:
    lines = ["soak: " + ", ".join(f"{name} {'ok' if ok else 'MISSED'}" for name, ok in verdict["checks"].items())]
    if verdict["services_short"]:
        lines.append("  short of rate or over the misses budget: " + ", ".join(verdict["services_short"]))
    return "\n".join(lines)


def bench_soak_command(args: argparse.Namespace) -> int:
    import logging
    import sys

    from feelium.daemon.journal import setup_logging

    setup_logging(logging.WARNING)
    if not args.minutes > 0:
        print("feelium bench soak: --minutes must be positive", file=sys.stderr)
        return 2
    result = bench_board(load_config(args.config), args.minutes)
    result["soak"] = soak_verdict(result)
    emit_report(format_table(result) + "\n" + format_verdict(result["soak"]), result, args.json)
    return 0 if result["soak"]["holds"] else 1
