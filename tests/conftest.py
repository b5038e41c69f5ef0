"""Shared test settings.

Hypothesis is deterministic so CI never flakes on a new example. The async tests run on asyncio's own loop;
``FEELIUM_TEST_EVENT_LOOP=uvloop`` runs every one of them on uvloop, the loop the daemon runs on
(docs/daemon.md), to find code that leans on one loop's order of callbacks. The suite runs on every core (pytest-xdist,
one whole module per worker so a module's expensive fixtures are built once); the modules that take longest
are handed out first, so the workers finish together instead of one waiting for the last long module.
"""

from __future__ import annotations

import asyncio
import os

import pytest
from hypothesis import settings

if os.environ.get("FEELIUM_TEST_EVENT_LOOP") == "uvloop":
    import uvloop

    asyncio.set_event_loop_policy(uvloop.EventLoopPolicy())

settings.register_profile("feelium", derandomize=True, deadline=None, max_examples=60)
settings.load_profile("feelium")

# Longest first, measured with `pytest --durations=60` (2026-11-26): the first two fly their plants in a
# process pool of their own; the rest simulate datasets or start processes.
LONGEST_MODULES = (
    "tests/flight/test_random_plants.py",
    "tests/flight/test_calibrate_flight.py",
    "tests/touch/test_end_to_end.py",
    "tests/projector/test_facevideo.py",
    "tests/http/test_browser.py",
    "tests/projector/test_exchanges.py",
    "tests/sim/test_conditions.py",
    "tests/sim/test_paper_protocol.py",
    "tests/touch/test_reference.py",
    "tests/deploy/test_pi_install.py",
    "tests/projector/test_renderer.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Put the longest modules first, keeping every module's own order."""
    rank = {path: position for position, path in enumerate(LONGEST_MODULES)}
    order = {id(item): position for position, item in enumerate(items)}

    def key(item: pytest.Item) -> tuple[int, int]:
        path = item.nodeid.split("::", 1)[0]
        return rank.get(path, len(rank)), order[id(item)]

    items.sort(key=key)
