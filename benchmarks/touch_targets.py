"""The touch targets of issue 2 on the simulated paper protocol, seed by seed, in one table.

    python benchmarks/touch_targets.py [--root /tmp/touch-ds] [--seeds 1 2 3] [--jobs 3] [--json FILE]

For each seed: simulate the full protocol into ROOT/seedN unless it is already
there, run `feelium eval` with the default thresholds and with
`--fit-on-clips` (reports and figures land beside the datasets), then print
every target against every seed and mode, with PASS/MISS. Nothing is
computed here: every number comes from the `feelium eval` reports.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, Callable

MODES = {"default": [], "fit-on-clips": ["--fit-on-clips"]}


def _get(report: dict[str, Any], *keys: str) -> Any:
    value: Any = report
    for key in keys:
        if value is None:
            return None
        value = value.get(key)
    return value


# (name, extractor, comparison, goal)
TARGETS: list[tuple[str, Callable[[dict[str, Any]], Any], str, float]] = [
    ("trial precision", lambda r: _get(r, "trials", "precision"), ">=", 0.97),
    ("trial recall", lambda r: _get(r, "trials", "recall"), ">=", 0.97),
    ("events in empty trials", lambda r: _get(r, "trials", "by_label", "empty", "fired"), "<=", 0),
    ("anchoring AUC", lambda r: _get(r, "sustained", "auc"), ">=", 0.99),
    ("hold-out balanced acc.", lambda r: _get(r, "sustained", "balanced_accuracy_holdout"), ">=", 0.95),
    ("kind accuracy", lambda r: _get(r, "trials", "kind_accuracy"), ">=", 0.95),
    ("single-event rate", lambda r: _get(r, "trials", "single_event_rate"), ">=", 0.95),
    ("localisation median px", lambda r: _get(r, "localisation", "error_px", "median"), "<=", 3.0),
    ("tap onset latency med ms", lambda r: _get(r, "latency_ms", "median"), "<=", 150.0),
]
INFO: list[tuple[str, Callable[[dict[str, Any]], Any]]] = [
    ("F1", lambda r: _get(r, "trials", "f1")),
    ("fp / fn", lambda r: f"{_get(r, 'trials', 'fp')} / {_get(r, 'trials', 'fn')}"),
    ("hover trials fired", lambda r: _get(r, "trials", "by_label", "hover", "fired")),
    ("disturbances fired", lambda r: _get(r, "trials", "by_label", "disturbance", "fired")),
    ("area-only precision", lambda r: _get(r, "area_baseline", "precision")),
    ("activity hand / empty", lambda r: f"{_get(r, 'activity', 'registered')}/{_get(r, 'activity', 'hand_present')}"
     f" / {_get(r, 'activity', 'empty_fired')}"),
    ("gates: instant / anchor", lambda r: f"{_get(r, 'touch_config', 'instant_depth'):.3f}"
     f" / {_get(r, 'touch_config', 'anchor_threshold'):.3f}"),
    ("ms/frame median", lambda r: _get(r, "speed", "ms_per_frame", "median")),
]


def _has_dataset(path: Path) -> bool:
    return path.is_dir() and any(path.rglob("meta.json"))


def prepare(root: Path, seed: int) -> Path:
    dataset = root / f"seed{seed}"
    if not _has_dataset(dataset):
        subprocess.run(
            ["feelium", "simulate", "paper-protocol", "--out", str(dataset), "--seed", str(seed), "--jobs", "1",
             "--no-thermal", "--quiet"],
            check=True,
        )
    return dataset


def evaluate(root: Path, seed: int, mode: str) -> dict[str, Any]:
    dataset = prepare(root, seed)
    report = root / f"seed{seed}-{mode}.json"
    subprocess.run(
        ["feelium", "eval", str(dataset), "--json", str(report), "--figure", str(report.with_suffix(".png")),
         *MODES[mode]],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    return json.loads(report.read_text())


def _cell(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 10 else f"{value:.1f}"
    return str(value)


def _passes(value: Any, op: str, goal: float) -> bool:
    return value is not None and (value >= goal if op == ">=" else value <= goal)


def table(reports: dict[tuple[int, str], dict[str, Any]]) -> tuple[str, dict[str, Any]]:
    columns = sorted(reports)
    head = ["target", "goal"] + [f"seed {s} {m}" for s, m in columns]
    rows, summary = [], {}
    for name, get, op, goal in TARGETS:
        cells = [name, f"{op} {goal:g}"]
        for col in columns:
            value = get(reports[col])
            ok = _passes(value, op, goal)
            cells.append(f"{_cell(value)} {'PASS' if ok else 'MISS'}")
            summary.setdefault(name, {})[f"seed{col[0]}-{col[1]}"] = {"value": value, "pass": ok}
        rows.append(cells)
    for name, get in INFO:
        rows.append([name, ""] + [_cell(get(reports[col])) for col in columns])
    widths = [max(len(r[i]) for r in [head] + rows) for i in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(head, widths)), "  ".join("-" * w for w in widths)]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(lines), summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default="/tmp/touch-ds", help="where the datasets and reports live")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--modes", nargs="+", default=list(MODES), choices=list(MODES))
    parser.add_argument("--jobs", type=int, default=3, help="evaluations run in parallel")
    parser.add_argument("--json", help="write the per-target summary here")
    args = parser.parse_args(argv)
    root = Path(args.root)
    root.mkdir(parents=True, exist_ok=True)
    for seed in args.seeds:  # simulate first (each seed once, even when both modes need it)
        prepare(root, seed)
    jobs = [(seed, mode) for seed in args.seeds for mode in args.modes]
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = dict(zip(jobs, pool.map(lambda job: evaluate(root, *job), jobs)))
    text, summary = table(results)
    print(text)
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return 0 if all(v["pass"] for per in summary.values() for v in per.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
