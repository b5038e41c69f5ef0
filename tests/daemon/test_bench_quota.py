"""``feelium bench quota``: the quota derived from the projected budget on this host, set, put back, judged.

The cgroup is a directory of plain files here (the kernel's interface is files too); the bench runs are stand-ins
with the figures a real run reports, so these tests check the arithmetic and the bookkeeping, not the speed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from feelium.daemon.config import Config
from feelium.lab.daemon.attribution import SIM_DEVICES
from feelium.lab.daemon.budgetquota import QUOTA_CHECKS, bench_quota, quota_for_budget, quota_verdict
from feelium.lab.daemon.projection import check_budget
from feelium.lab.daemon.quota import quota_of, restore_quota, set_quota


def v1_group(tmp_path: Path, quota: str = "-1", period: str = "100000") -> Path:
    (tmp_path / "cpu.cfs_quota_us").write_text(quota + "\n")
    (tmp_path / "cpu.cfs_period_us").write_text(period + "\n")
    (tmp_path / "cgroup.procs").write_text("")
    return tmp_path


def run(process_ms: float = 210.0, pi_cores: float = 1.68, sim_ms: float = 6.0, touch_rate: float = 30.0,
        touch_miss: float = 0.0, lag_p99: float = 3.0, flight_rate: float = 50.0) -> dict[str, Any]:
    """A board bench result's keys this module reads, its budget lines judged by the projection's own check."""
    result: dict[str, Any] = {
        "process_cpu_ms_per_s": process_ms,
        "pi_cores": pi_cores,
        "pi_factor": "measured split (6x numeric, 10x Python-level)",
        "loop_lag_p99_ms": lag_p99,
        "rss_mb": 142.0,
        "rss_peak_mb": 153.0,
        "services": {
            "touch": {"rate_hz": touch_rate, "target_hz": 30.0, "miss_pct": touch_miss, "cpu_ms_per_s": 80.0},
            "flight": {"rate_hz": flight_rate, "target_hz": 50.0, "miss_pct": 0.2, "cpu_ms_per_s": 25.0},
            SIM_DEVICES: {"rate_hz": None, "target_hz": None, "miss_pct": None, "cpu_ms_per_s": sim_ms},
        },
    }
    result["budget"] = check_budget(result, pi_cores=2.5, loop_thread_ms=30.0)  # over the budget: never judged inside the quota
    return result


def test_the_quota_is_the_budget_over_the_factor_measured_here_plus_the_simulated_devices():
    derived = quota_for_budget(run(process_ms=210.0, pi_cores=1.63, sim_ms=6.0))
    factor = 1.63 / 0.204  # projected over the cores used here without the simulated sensor
    assert derived["factor"] == pytest.approx(factor, abs=1e-3)
    assert derived["quota_us"] == round((2.0 / factor + 0.006) * 10_000)
    # A host twice as slow projects twice the Pi cores at the same factor (the projection is per core here): the
    # quota is the same share of a core, but for the simulated devices' larger share.
    slower = quota_for_budget(run(process_ms=420.0, pi_cores=1.63 * 2.0, sim_ms=12.0))
    assert slower["quota_us"] - derived["quota_us"] == 60
    # A split that finds more numeric work (a smaller factor) gives a larger quota for the same budget.
    assert quota_for_budget(run(pi_cores=1.4))["quota_us"] > quota_for_budget(run(pi_cores=1.7))["quota_us"]
    with pytest.raises(ValueError):
        quota_for_budget(run(process_ms=6.0, sim_ms=6.0))  # nothing but the simulated devices measured
    # A period so short that the budget is under the kernel's floor: refused, never raised to the floor (which
    # would hand out more than the budget and still call it the budget).
    assert quota_for_budget(run(), period_us=5_000)["quota_us"] >= 1_000
    with pytest.raises(ValueError, match="longer period"):
        quota_for_budget(run(), period_us=4_000)


def test_set_quota_writes_v1_and_v2_and_restore_puts_the_old_one_back(tmp_path):
    (tmp_path / "v1").mkdir()
    v1 = v1_group(tmp_path / "v1")
    before = set_quota(v1, 2475, 10_000)
    assert before == "-1 100000" and quota_of(v1) == "2475 10000"
    restore_quota(v1, before)
    assert quota_of(v1) == "-1 100000"
    v2 = tmp_path / "v2"
    v2.mkdir()
    (v2 / "cpu.max").write_text("max 100000\n")
    before = set_quota(v2, 2000, 10_000)
    assert before == "max 100000" and quota_of(v2) == "2000 10000"
    restore_quota(v2, before)
    assert quota_of(v2) == "max 100000"


def test_the_confined_run_gets_the_derived_quota_and_the_group_is_restored_even_if_it_fails(tmp_path):
    group = v1_group(tmp_path)
    calls: list[dict[str, Any]] = []

    def unconfined() -> dict[str, Any]:
        calls.append({"quota": quota_of(group)})
        return run()

    def bench(config: Config, minutes: float, **kw: Any) -> dict[str, Any]:
        calls.append({"minutes": minutes, "quota": quota_of(group), **kw})
        return run(touch_rate=27.0)

    result = bench_quota(Config(), group, 2.0, unconfined=unconfined, bench=bench)
    first, confined = calls
    assert first["quota"] == "-1 100000"  # the factor is measured before the quota is set
    assert confined["cgroup"] == group and confined["numeric_split_s"] == 0.0 and confined["minutes"] == 2.0
    assert confined["quota"] == f"{result['quota']['quota_us']} 10000"
    assert quota_of(group) == "-1 100000"  # put back
    assert not result["verdict"]["holds"] and result["verdict"]["services_short"] == ["touch"]

    def crashing(config: Config, minutes: float, **kw: Any) -> dict[str, Any]:
        raise RuntimeError("the daemon died")

    with pytest.raises(RuntimeError):
        bench_quota(Config(), group, 2.0, unconfined=run, bench=crashing)
    assert quota_of(group) == "-1 100000"


def test_a_given_quota_skips_the_unconfined_run(tmp_path):
    group = v1_group(tmp_path)
    seen: list[str] = []

    def bench(config: Config, minutes: float, **kw: Any) -> dict[str, Any]:
        seen.append(quota_of(group))
        return run()

    result = bench_quota(Config(), group, 1.0, quota_us=2200, bench=bench)
    assert seen == ["2200 10000"] and result["unconfined"] is None and result["verdict"]["holds"]


def test_the_verdict_judges_rates_misses_and_lag_not_the_projection():
    assert quota_verdict(run())["holds"]  # the stand-in's pi_cores line is missed and does not count
    assert not quota_verdict(run(touch_miss=1.5))["holds"]
    assert not quota_verdict(run(lag_p99=25.0))["holds"]
    short = quota_verdict(run(flight_rate=48.0))
    assert not short["holds"] and short["services_short"] == ["flight"]
    assert quota_verdict(run(touch_rate=29.2))["holds"]  # 97 % of 30 is 29.1
    assert set(quota_verdict(run())["checks"]) == set(QUOTA_CHECKS)


def test_a_refused_write_leaves_the_group_as_it_was(tmp_path, monkeypatch):
    """v1 writes the period, then the quota: a kernel that refuses the quota (a parent's lower quota) must not
    leave the new period behind."""
    group = v1_group(tmp_path, quota="2475", period="10000")
    real_write = Path.write_text
    refused = {"count": 0}

    def write_text(self: Path, text: str, *args: Any, **kw: Any) -> int:
        if self.name == "cpu.cfs_quota_us" and text.strip() == "3000" and not refused["count"]:
            refused["count"] += 1
            raise OSError(22, "Invalid argument")
        return real_write(self, text, *args, **kw)

    monkeypatch.setattr(Path, "write_text", write_text)
    with pytest.raises(OSError):
        set_quota(group, 3000, 20_000)
    assert quota_of(group) == "2475 10000"


def test_a_group_that_is_shared_or_not_a_cpu_group_is_refused_and_a_made_one_removed(tmp_path):
    from feelium.lab.daemon.budgetquota import _group

    fresh = tmp_path / "fresh"
    with pytest.raises(OSError, match="cpu controller"):
        _group(str(fresh))  # made, not a cgroup (plain directory): refused and removed again
    assert not fresh.exists()
    busy = v1_group(tmp_path)
    (busy / "cgroup.procs").write_text("1234\n")
    with pytest.raises(OSError, match="already holds processes"):
        _group(str(busy))
    (busy / "cgroup.procs").write_text("")
    (busy / "child").mkdir()
    with pytest.raises(OSError, match="child groups"):
        _group(str(busy))
    (busy / "child").rmdir()
    assert _group(str(busy)) == busy


def test_the_command_refuses_a_group_without_the_cpu_controller_before_running(tmp_path, capsys):
    from feelium.cli import main

    assert main(["bench", "quota", "--cgroup", str(tmp_path), "--minutes", "1"]) == 2
    assert "cpu.max" in capsys.readouterr().err
    group = str(v1_group(tmp_path))
    for bad in (["--quota-us", "500"], ["--period-us", "0"], ["--period-us", "2000000"], ["--numeric-split-seconds", "nan"],
                ["--numeric-split-seconds", "-1"], ["--minutes", "inf"], ["--calibrate-minutes", "0"]):
        assert main(["bench", "quota", "--cgroup", group, *bad]) == 2, bad
    assert quota_of(tmp_path) == "-1 100000"  # nothing was set


def test_the_unconfined_run_is_the_board_bench_in_a_child_process(monkeypatch):
    import json
    import subprocess

    from feelium.lab.daemon import budgetquota

    seen: list[list[str]] = []

    class Child:
        def __init__(self, command: list[str], **kw: Any) -> None:
            seen.append(command)
            assert kw["start_new_session"]  # a Ctrl-C reaches it through terminate(), so its own cleanup runs
            Path(command[command.index("--json") + 1]).write_text(json.dumps(run()))

        def wait(self) -> int:
            return 0

        def poll(self) -> int:
            return 0

    monkeypatch.setattr(subprocess, "Popen", Child)
    assert budgetquota.unconfined_in_child("blimp.toml", 0.5, 15.0) == run()
    (command,) = seen
    assert command[1:5] == ["-m", "feelium", "bench", "board"]
    assert command[command.index("--minutes") + 1] == "0.5" and command[command.index("--numeric-split-seconds") + 1] == "15.0"
    assert command[-2:] == ["--config", "blimp.toml"]


def test_the_report_says_what_the_quota_came_from(tmp_path, monkeypatch):
    from feelium.lab.daemon import budgetquota

    monkeypatch.setattr(budgetquota, "format_table", lambda result: "table")
    group = v1_group(tmp_path)
    derived = budgetquota.format_quota(bench_quota(Config(), group, 1.0, unconfined=run, bench=lambda *a, **kw: run(touch_miss=2.0)))
    assert "projected 1.68 Pi cores" in derived and "missed pi_cores <= 2.0" in derived  # the stand-in's unconfined run
    assert "every service < 1 % misses MISSED" in derived and "touch" in derived.splitlines()[-1]
    fallback = {**run(), "pi_factor": 10.0}
    text = budgetquota.format_quota(bench_quota(Config(), group, 1.0, unconfined=lambda: fallback, bench=lambda *a, **kw: run()))
    assert "no numeric split" in text
    given = budgetquota.format_quota(bench_quota(Config(), group, 1.0, quota_us=20_000, bench=lambda *a, **kw: run()))
    assert "quota 20000 us per 10000 us (given)" in given
