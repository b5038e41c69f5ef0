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
from feelium.lab.daemon.quota import quota_of, restore_quota, set_quota


def v1_group(tmp_path: Path, quota: str = "-1", period: str = "100000") -> Path:
    (tmp_path / "cpu.cfs_quota_us").write_text(quota + "\n")
    (tmp_path / "cpu.cfs_period_us").write_text(period + "\n")
    (tmp_path / "cgroup.procs").write_text("")
    return tmp_path


def run(process_ms: float = 210.0, pi_cores: float = 1.68, sim_ms: float = 6.0, touch_rate: float = 30.0,
        touch_miss: float = 0.0, lag_p99: float = 3.0) -> dict[str, Any]:
    budget = {name: True for name in QUOTA_CHECKS}
    budget["every service >= 97 % of target"] = touch_rate >= 29.1
    budget["touch at 30 fps"] = touch_rate >= 29.1
    budget["every service < 1 % misses"] = touch_miss < 1.0
    budget["loop lag p99 <= 20 ms"] = lag_p99 <= 20.0
    budget["pi_cores <= 2.0"] = False  # a quota cannot break what it is: never judged inside it
    return {
        "process_cpu_ms_per_s": process_ms,
        "pi_cores": pi_cores,
        "pi_factor": "measured split (6x numeric, 10x Python-level)",
        "budget": budget,
        "services": {
            "touch": {"rate_hz": touch_rate, "target_hz": 30.0, "miss_pct": touch_miss, "cpu_ms_per_s": 80.0},
            "flight": {"rate_hz": 50.0, "target_hz": 50.0, "miss_pct": 0.2, "cpu_ms_per_s": 25.0},
            SIM_DEVICES: {"rate_hz": None, "target_hz": None, "miss_pct": None, "cpu_ms_per_s": sim_ms},
        },
    }


def test_the_quota_is_the_budget_over_the_factor_measured_here_plus_the_simulated_devices():
    derived = quota_for_budget(run(process_ms=210.0, pi_cores=1.63, sim_ms=6.0))
    factor = 1.63 / 0.204  # projected over the cores used here without the simulated sensor
    assert derived["factor"] == pytest.approx(factor, abs=1e-3)
    assert derived["quota_us"] == round((2.0 / factor + 0.006) * 10_000)
    # A host twice as slow projects twice the Pi cores at the same factor (the projection is per core here): the
    # quota is the same share of a core, plus the simulated sensor's larger share, and the projection fails first.
    slower = quota_for_budget(run(process_ms=420.0, pi_cores=1.63 * 2.0, sim_ms=12.0))
    assert slower["factor"] == pytest.approx(derived["factor"], rel=0.03)
    assert slower["quota_us"] - derived["quota_us"] == pytest.approx(60 + 10_000 * 2.0 * (1 / slower["factor"] - 1 / derived["factor"]), abs=1)
    # A split that finds more numeric work (a smaller factor) gives a larger quota for the same budget.
    assert quota_for_budget(run(pi_cores=1.4))["quota_us"] > quota_for_budget(run(pi_cores=1.7))["quota_us"]
    with pytest.raises(ValueError):
        quota_for_budget(run(process_ms=6.0, sim_ms=6.0))  # nothing but the simulated devices measured


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
    assert quota_verdict(run())["holds"]  # pi_cores' line is False in the stand-in and does not count
    assert not quota_verdict(run(touch_miss=1.5))["holds"]
    assert not quota_verdict(run(lag_p99=25.0))["holds"]
    assert set(quota_verdict(run())["checks"]) == set(QUOTA_CHECKS)


def test_the_command_refuses_a_group_without_the_cpu_controller_before_running(tmp_path, capsys):
    from feelium.cli import main

    assert main(["bench", "quota", "--cgroup", str(tmp_path), "--minutes", "1"]) == 2
    assert "cpu.max" in capsys.readouterr().err
    assert main(["bench", "quota", "--cgroup", str(v1_group(tmp_path)), "--quota-us", "500"]) == 2


def test_the_unconfined_run_is_the_board_bench_in_a_child_process(monkeypatch):
    import json
    import subprocess

    from feelium.lab.daemon import budgetquota

    seen: list[list[str]] = []

    def child(command: list[str], **kw: Any) -> subprocess.CompletedProcess:
        seen.append(command)
        Path(command[command.index("--json") + 1]).write_text(json.dumps(run()))
        return subprocess.CompletedProcess(command, 0)

    monkeypatch.setattr(subprocess, "run", child)
    assert budgetquota.unconfined_in_child("blimp.toml", 0.5, 15.0) == run()
    (command,) = seen
    assert command[1:5] == ["-m", "feelium", "bench", "board"]
    assert command[command.index("--minutes") + 1] == "0.5" and command[command.index("--numeric-split-seconds") + 1] == "15.0"
    assert command[-2:] == ["--config", "blimp.toml"]
