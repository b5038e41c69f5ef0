"""How a ``feelium bench`` command hands its result over: the table for a person, the JSON for a file or a pipe."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def emit_report(table: str, result: dict[str, Any], json_path: str | None) -> None:
    """Print ``table``; write ``result`` as JSON to ``json_path``, or print it after the table when none is given."""
    print(table)
    text = json.dumps(result, indent=1)
    if json_path:
        Path(json_path).write_text(text + "\n", encoding="utf-8")
    else:
        print(text)
