"""Log lines for journald and for a terminal.

Under systemd (``JOURNAL_STREAM`` or ``INVOCATION_ID`` set) each line starts
with a syslog priority prefix (``<3>`` error ... ``<7>`` debug) that journald
turns into the entry's priority, and carries no timestamp (journald adds
one). In a terminal lines carry a short time instead.
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Mapping
from typing import TextIO

PRIORITIES = {logging.CRITICAL: 2, logging.ERROR: 3, logging.WARNING: 4, logging.INFO: 6, logging.DEBUG: 7}
LEVELS = {"debug": logging.DEBUG, "info": logging.INFO, "warning": logging.WARNING, "error": logging.ERROR}


def under_systemd(environ: Mapping[str, str] = os.environ) -> bool:
    return "JOURNAL_STREAM" in environ or "INVOCATION_ID" in environ


class JournalFormatter(logging.Formatter):
    """``<6>feelium.touch: message``, tracebacks indented on the lines that follow."""

    def format(self, record: logging.LogRecord) -> str:
        priority = PRIORITIES.get(record.levelno, 6 if record.levelno < logging.WARNING else 3)
        text = super().format(record)
        return "\n".join(f"<{priority}>{line}" for line in text.splitlines())


def effective_level(configured: str, verbose: int) -> int:
    """The config's level, lowered to debug by ``-v``."""
    return logging.DEBUG if verbose > 0 else LEVELS[configured]


def setup_logging(level: int, *, journal: bool | None = None, stream: TextIO | None = None) -> None:
    """Route the root logger to stdout in journald or terminal form (replacing earlier handlers)."""
    journal = under_systemd() if journal is None else journal
    handler = logging.StreamHandler(stream if stream is not None else sys.stdout)
    if journal:
        handler.setFormatter(JournalFormatter("%(name)s: %(message)s"))
    else:
        handler.setFormatter(logging.Formatter("%(asctime)s.%(msecs)03d %(levelname)-7s %(name)s: %(message)s", "%H:%M:%S"))
    root = logging.getLogger()
    for old in list(root.handlers):
        root.removeHandler(old)
    root.addHandler(handler)
    root.setLevel(level)
    for noisy in ("aiohttp.access", "asyncio"):
        logging.getLogger(noisy).setLevel(max(level, logging.WARNING))
