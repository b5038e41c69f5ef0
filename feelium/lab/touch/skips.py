"""Bad recordings are left out of a dataset run, one line each, instead of ending it.

A dataset collected on the blimp over days will hold the odd broken take; `feelium replay`, `eval` and
`calibrate touch` score the good ones, name each skipped file with its problem as they meet it, and
sum up at the end. Exit codes: 0 every recording was used, 3 some were skipped (``SKIPPED_EXIT``), 1 every
one was (``NOTHING_USABLE_EXIT``: nothing was scored, as when there is no recording at all).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TextIO, TypeVar

from feelium.recording import Recording, RecordingError, check_labels_fit, find_recordings

SKIPPED_EXIT = 3
NOTHING_USABLE_EXIT = 1

T = TypeVar("T")


class Skips:
    """The recordings one command left out, reported to ``err`` as they happen and summed up at the end."""

    def __init__(self, command: str, err: TextIO | None = None, *, scores_labels: bool = False) -> None:
        """``scores_labels``: the command scores against the labels, so labels that contradict themselves or
        their take (:func:`feelium.recording.check_labels_fit`) make a recording bad too."""
        self.command = command
        self.scores_labels = scores_labels
        self.err = err if err is not None else sys.stderr
        self.problems: list[RecordingError] = []
        self.seen = 0

    def recordings(self, root: Path) -> Iterator[Recording]:
        """Every recording under ``root`` that opens cleanly; the others are reported and left out."""
        for path in find_recordings(root):
            self.seen += 1
            try:
                recording = Recording(path)
                if self.scores_labels:
                    check_labels_fit(recording)
            except RecordingError as exc:
                self.skip(exc)
                continue
            yield recording

    def attempt(self, work: Callable[[], T]) -> T | None:
        """``work()``, or ``None`` after reporting it when a recording turns out bad half-way (e.g. its video ends early)."""
        try:
            return work()
        except RecordingError as exc:
            self.skip(exc)
            return None

    def skip(self, problem: RecordingError) -> None:
        self.problems.append(problem)
        print(f"feelium {self.command}: skipped {problem}", file=self.err)

    def finish(self) -> int:
        """Print which recordings were skipped (if any) and return the exit code."""
        if not self.problems:
            return 0
        names = ", ".join(str(p.path) for p in self.problems)
        print(f"feelium {self.command}: skipped {len(self.problems)} of {self.seen} recordings: {names}", file=self.err)
        return NOTHING_USABLE_EXIT if len(self.problems) >= self.seen else SKIPPED_EXIT
