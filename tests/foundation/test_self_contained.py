"""The project carries its own contracts: nothing it ships points at files outside the repository."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
OUTSIDE = ("shared/specs", "shared/design", "shared/vendor", "shared/seed", "../shared", "/work/")
THIS = Path(__file__).resolve().relative_to(ROOT).as_posix()


def _tracked_text_files() -> list[Path]:
    try:
        listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: cannot list the project's files")
    names = [n for n in listed.decode().split("\0") if n and n != THIS]
    return [ROOT / n for n in names if (ROOT / n).suffix in {".py", ".md", ".toml", ".txt", ".sh", ".service", ""}]


def test_no_file_points_outside_the_repository() -> None:
    hits = []
    for path in _tracked_text_files():
        if not path.is_file():
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        hits += [f"{path.relative_to(ROOT)}: {needle}" for needle in OUTSIDE if needle in text]
    assert not hits, hits


@pytest.mark.parametrize("name", ["recording-format.md", "evaluation.md"])
def test_the_contracts_are_in_docs(name: str) -> None:
    text = (ROOT / "docs" / name).read_text(encoding="utf-8")
    assert "version 1" in text.splitlines()[2]
