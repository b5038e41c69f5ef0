"""The daemon benchmark's numbers are produced and consistent; the malloc arena cap applies on glibc."""

from __future__ import annotations

import platform

import pytest

from feelium.config import Config
from feelium.daemon.bench import bench_daemon, format_table
from feelium.daemon.memory import limit_malloc_arenas


def test_arena_cap_is_a_no_op_at_zero_and_applies_on_glibc():
    assert limit_malloc_arenas(0) is False
    if platform.libc_ver()[0] == "glibc":
        assert limit_malloc_arenas(2) is True


@pytest.mark.slow
def test_bench_daemon_measures_memory_cpu_and_frames():
    result = bench_daemon(Config(), 2.0)
    assert result["rear_frames"] > 5
    assert 0 < result["rss_mb_median"] <= result["rss_mb_max"]
    assert result["process_cpu_ms_per_rear_frame"] > result["baseline"]["pipeline_ms_median"] > 0
    assert result["dropped_rear_frames"] >= 0 and result["services"]["touch"] == "running"  # measured while running
    table = format_table(result)
    assert "resident memory" in table and "pipeline alone" in table
