"""``feelium bench soak``'s verdict: each long-uptime goal of issue 15 judged on the board bench's figures."""

from __future__ import annotations

from typing import Any

from feelium.lab.daemon.soak import format_verdict, soak_verdict


def result(rss: float = 140.0, growth: float | None = 1.0, touch_rate: float = 30.0, touch_miss: float = 0.0) -> dict[str, Any]:
    return {
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
    assert not soak_verdict(result(growth=5.0))["checks"]["growth after warm-up < 5 MB"]
    assert not soak_verdict(result(growth=None))["holds"]  # too short to tell a leak from warm-up: not a pass
    short = soak_verdict(result(touch_rate=28.0))
    assert short["services_short"] == ["touch"] and not short["holds"]
    assert soak_verdict(result(touch_miss=1.5))["services_short"] == ["touch"]
    assert "MISSED" in format_verdict(short) and "touch" in format_verdict(short)
