"""How a ``feelium bench`` command hands its result over: the table for a person, the JSON for a file or a pipe."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any


def finite_or_null(value: object) -> object:
    """``value`` with every NaN or infinite float as ``None``: JSON has no NaN, and a strict parser (a browser's, Node's)
    rejects the whole file for one. An unfitted value or a flight that never stopped is then ``null``."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite_or_null(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_null(item) for item in value]
    return value


def emit_report(table: str, result: dict[str, Any], json_path: str | None) -> None:
    """Print ``table``; write ``result`` as JSON to ``json_path``, or print it after the table when none is given."""
    print(table)
    text = json.dumps(finite_or_null(result), indent=1, allow_nan=False)
    if json_path:
        Path(json_path).write_text(text + "\n", encoding="utf-8")
    else:
        print(text)


def print_and_save(report: dict[str, Any], json_path: str | None, *, indent: int | None = None) -> None:
    """A benchmark's report: printed as JSON (one line unless ``indent``), and written indented to ``json_path`` if given."""
    report = finite_or_null(report)  # type: ignore[assignment]
    print(json.dumps(report, indent=indent, allow_nan=False))
    if json_path:
        Path(json_path).write_text(json.dumps(report, indent=2, allow_nan=False) + "\n", encoding="utf-8")


def print_progress(n: int, total: int, name: str) -> None:
    """One progress line on stderr, rewritten in place, for an experiment that takes minutes."""
    print(f"\r{n}/{total} {name:<30}", end="", file=sys.stderr, flush=True)


def finish_experiment(table: str, report: dict[str, Any], json_path: str | None, *, progressed: bool = True) -> int:
    """The end of a lab experiment's run: close the progress line, write the JSON if asked, print the table."""
    if progressed:
        print(file=sys.stderr)
    if json_path:
        Path(json_path).write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    print(table)
    return 0
