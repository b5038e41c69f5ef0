"""``feelium bench soak``'s verdict: each long-uptime goal of issue 15 judged on the board bench's figures."""

from __future__ import annotations

from typing import Any

from feelium.lab.daemon.soak import format_verdict, soak_verdict


GROWTH = "growth after warm-up < 5 MB (judged from 10 minutes on)"


def result(
    rss: float = 140.0, growth: float | None = 1.0, touch_rate: float = 30.0, touch_miss: float = 0.0, seconds: float = 1800.0
) -> dict[str, Any]:
    return {
        "seconds": seconds,
        "rss_mb": rss,
        "rss_growth_mb": growth,
        "services": {
            "touch": {"rate_hz": touch_rate, "target_hz": 30.0, "miss_pct": touch_miss},
            "flight": {"rate_hz": 50.0, "target_hz": 50.0, "miss_pct": 0.2},
            "other threads": {"rate_hz": None, "target_hz": None, "miss_pct": None},
        },
    }


def test_a_clean_long_run_holds():
    verdict = soak_verdict(result())
    assert verdict["holds"] and verdict["services_short"] == []


def test_each_goal_fails_on_its_own():
    assert not soak_verdict(result(rss=151.0))["checks"]["RSS steady <= 150 MB"]
    assert not soak_verdict(result(growth=5.0))["checks"][GROWTH]
    assert not soak_verdict(result(growth=None))["holds"]  # too short to tell a leak from warm-up: not a pass
    assert not soak_verdict(result(seconds=599.0))["checks"][GROWTH]  # a minute's growth says nothing of a leak
    short = soak_verdict(result(touch_rate=28.0))
    assert short["services_short"] == ["touch"] and not short["holds"]
    assert soak_verdict(result(touch_miss=1.5))["services_short"] == ["touch"]
    assert "MISSED" in format_verdict(short) and "touch" in format_verdict(short)


def test_the_command_exits_1_when_the_verdict_fails(monkeypatch, tmp_path):
    from feelium.cli import main
    from feelium.lab.daemon import soak

    figures = {**result(rss=180.0), "services": {}, "cpu_quota": None}
    monkeypatch.setattr(soak, "bench_board", lambda config, minutes: dict(figures))
    monkeypatch.setattr(soak, "format_table", lambda r: "table")
    assert main(["bench", "soak", "--minutes", "1", "--json", str(tmp_path / "s.json")]) == 1
    monkeypatch.setattr(soak, "bench_board", lambda config, minutes: {**result(), "cpu_quota": None})
    assert main(["bench", "soak", "--minutes", "30", "--json", str(tmp_path / "s.json")]) == 0
