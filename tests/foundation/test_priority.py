"""Bulk-work threads run nicer than the flight loop's, so a short CPU serves flight first (feelium.priority)."""

from __future__ import annotations

import asyncio
import logging
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import pytest

from feelium import priority
from feelium.cameras.reader import Worker


def _nice_of_a_thread_started_by(start: ThreadPoolExecutor) -> int:
    return start.submit(lambda: priority.thread_nice(threading.get_native_id())).result()


@pytest.fixture
def nice(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    monkeypatch.setattr(priority, "_background_nice", 0)
    monkeypatch.setattr(priority, "_refused", threading.Event())
    return priority.set_background_nice


def test_a_camera_or_pipeline_worker_runs_nicer_than_the_process_and_a_plain_thread_does_not(nice) -> None:  # type: ignore[no-untyped-def]
    nice(7)
    base = os.getpriority(os.PRIO_PROCESS, os.getpid())
    worker = Worker("touch-pipeline")
    try:
        bulk = asyncio.run(worker.call(lambda: priority.thread_nice(threading.get_native_id())))
    finally:
        worker.shutdown()
    with ThreadPoolExecutor(1, thread_name_prefix="flight-serial") as serial:  # as the flight service makes it
        flight = _nice_of_a_thread_started_by(serial)
    assert bulk == min(19, base + 7)
    assert flight == base


def test_zero_leaves_every_thread_at_the_process_priority(nice) -> None:  # type: ignore[no-untyped-def]
    nice(0)
    base = os.getpriority(os.PRIO_PROCESS, os.getpid())
    with ThreadPoolExecutor(1, initializer=priority.lower_current_thread) as pool:
        assert _nice_of_a_thread_started_by(pool) == base


def test_a_refusal_is_logged_once_and_the_thread_runs_on(nice, monkeypatch, caplog) -> None:  # type: ignore[no-untyped-def]
    nice(10)

    def refuse(*_: object) -> None:
        raise PermissionError("not here")

    monkeypatch.setattr(priority.os, "setpriority", refuse)
    with caplog.at_level(logging.WARNING, logger="feelium.priority"):
        for _ in range(3):
            with ThreadPoolExecutor(1, initializer=priority.lower_current_thread) as pool:
                assert pool.submit(lambda: 42).result() == 42
    assert [r.getMessage() for r in caplog.records].count(caplog.records[0].getMessage()) == 1
    assert "refused" in caplog.records[0].getMessage()


def test_negative_or_huge_settings_are_clamped_to_what_the_kernel_accepts(nice) -> None:  # type: ignore[no-untyped-def]
    nice(-5)
    assert priority.background_nice() == 0
    nice(40)
    with ThreadPoolExecutor(1, initializer=priority.lower_current_thread) as pool:
        assert _nice_of_a_thread_started_by(pool) == 19


def test_auto_is_the_pis_value_on_a_pi_and_one_priority_elsewhere() -> None:
    from feelium.daemon.config import PI_BACKGROUND_NICE
    from feelium.daemon.runner import background_nice_here

    assert background_nice_here(-1, on_pi=True) == PI_BACKGROUND_NICE > 0
    assert background_nice_here(-1, on_pi=False) == 0
    assert background_nice_here(3, on_pi=False) == background_nice_here(3, on_pi=True) == 3
