"""From CPU measured here to CPU on a Pi Zero 2 W (four Cortex-A53 at 1 GHz), and the budget it must fit.

The factor: one core of the measuring machine against one A53 core at 1 GHz.
Published comparisons of the A53 (in-order, 2-wide, 1 GHz, 512 kB L2 shared)
with a recent x86 core (out-of-order, 3.5-5 GHz) put single-thread speed
apart by about 5-8x on vectorised numeric code (OpenCV and numpy use NEON on
the A53, which is narrower than AVX2) and by about 8-12x on interpreted
Python, where clock speed, branch prediction and cache sizes all count. Issue
16 fixes the two ends: 6x for numpy/OpenCV work, 10x for Python-level work.

Which share of each service's CPU is which is measured
(:mod:`feelium.lab.daemon.numeric`, a profiled window after the measured one):
each part of a service (its dedicated threads, its pool jobs) is projected at
``10 - 4 * share``, where ``share`` is the part's numeric share, a lower bound.
The event loop's thread and any CPU no service accounts for stay at 10x;
OpenCV's own worker threads run only native numeric code, at 6x. Without a
measured split every figure is projected at the conservative 10x, as before
2026-11-26. The totals at 10x and at 6x are always given beside it. The
simulated devices' own work (``SIM_DEVICES``, since 2026-11-27) is measured and
reported but projected at 0: the blimp runs the real sensor instead. The factors are per core of *this* machine, so a faster host projects a lighter
Pi: each report carries the host's CPU model and its time on two fixed workloads
(:mod:`feelium.lab.daemon.host`), and reports are compared only beside them. Replace
all of it with a run on the board itself (``feelium bench board`` runs there
unchanged) when one exists.
"""

from __future__ import annotations

from typing import Any

from feelium.lab.daemon.attribution import OTHER_THREADS, SIM_DEVICES

PI_CORES = 4
PI_FACTOR = 10.0  # Python-level work; every figure when no split was measured
PI_FACTOR_NUMERIC = 6.0  # numpy/OpenCV work
BUDGET = {
    "pi_cores": 2.0,  # half the board stays for the OS, Wi-Fi and bursts
    "rate_fraction": 0.97,
    "miss_pct": 1.0,
    "loop_lag_p99_ms": 20.0,
    "rss_mb": 150.0,
    "rss_peak_mb": 170.0,
}


def check_budget(result: dict[str, Any], pi_cores: float, loop_thread_ms: float) -> dict[str, bool]:
    """Each budget line of issue 16 and whether this run keeps it (rates and misses judged as measured here).

    ``loop_thread_ms``: the event loop thread's CPU per second without the simulated devices' share."""
    timed = {name: row for name, row in result["services"].items() if row.get("target_hz")}
    return {
        "pi_cores <= 2.0": pi_cores <= BUDGET["pi_cores"],
        "every service >= 97 % of target": all(row["rate_hz"] >= BUDGET["rate_fraction"] * row["target_hz"] for row in timed.values()),
        "every service < 1 % misses": all(row["miss_pct"] < BUDGET["miss_pct"] for row in timed.values()),
        "touch at 30 fps": "touch" in timed and timed["touch"]["target_hz"] >= 30 and timed["touch"]["rate_hz"] >= BUDGET["rate_fraction"] * 30,
        "event loop thread < 1 core": PI_FACTOR * loop_thread_ms < 1000.0,
        "loop lag p99 <= 20 ms": result["loop_lag_p99_ms"] <= BUDGET["loop_lag_p99_ms"],
        "RSS steady <= 150 MB": result["rss_mb"] <= BUDGET["rss_mb"],
        "RSS peak <= 170 MB": result["rss_peak_mb"] <= BUDGET["rss_peak_mb"],
    }


def part_factor(share: float) -> float:
    """The factor of a part of a service whose CPU is ``share`` numeric (0..1) and the rest Python-level."""
    return PI_FACTOR - (PI_FACTOR - PI_FACTOR_NUMERIC) * min(1.0, max(0.0, share))


def _pi_ms(name: str, row: dict[str, Any], shares: dict[str, dict[str, float]]) -> float:
    """One service's projected ms per second: each part at its measured factor (the loop's at 10x)."""
    if name == OTHER_THREADS:  # OpenCV's worker pool: native numeric code only, unless a sampler measured it
        measured = shares.get(OTHER_THREADS, {}).get("thread")
        return (PI_FACTOR_NUMERIC if measured is None else part_factor(measured)) * row["cpu_ms_per_s"]
    by_kind = row.get("cpu_ms_per_s_by_kind") or {"loop": row["cpu_ms_per_s"]}
    return sum(ms * (PI_FACTOR if kind == "loop" else part_factor(shares.get(name, {}).get(kind, 0.0))) for kind, ms in by_kind.items())


def project(result: dict[str, Any], shares: dict[str, dict[str, float]] | None = None) -> dict[str, Any]:
    """``pi_ms_per_s`` per service and the projected cores; adds to ``result['services']`` in place.

    ``shares``: the measured numeric share per service and part (:func:`feelium.lab.daemon.numeric.numeric_shares`);
    without it every figure is projected at 10x.
    """
    services = result["services"]
    sim = services.get(SIM_DEVICES, {})  # simulated hardware: the blimp runs none of it, so none is projected
    here_cores = (result["process_cpu_ms_per_s"] - sim.get("cpu_ms_per_s", 0.0)) / 1000.0
    loop_thread_ms = result["loop_thread_ms_per_s"] - (sim.get("cpu_ms_per_s_by_kind") or {}).get("loop", 0.0)
    if sim:
        sim["pi_ms_per_s"] = 0.0
    if shares is None:
        for name, row in services.items():
            if name != SIM_DEVICES:
                row["pi_ms_per_s"] = round(PI_FACTOR * row["cpu_ms_per_s"], 1)
        pi_cores = round(PI_FACTOR * here_cores, 2)
    else:
        charged = 0.0
        total = 0.0
        for name, row in services.items():
            if name == SIM_DEVICES:
                continue
            pi_ms = _pi_ms(name, row, shares)
            row["pi_ms_per_s"] = round(pi_ms, 1)
            if row["cpu_ms_per_s"] > 0:
                row["pi_factor"] = round(pi_ms / row["cpu_ms_per_s"], 2)
            charged += row["cpu_ms_per_s"]
            total += pi_ms
        unaccounted = max(0.0, 1000.0 * here_cores - charged)  # at 10x: nothing says it is numeric
        pi_cores = round((total + PI_FACTOR * unaccounted) / 1000.0, 2)
    return {
        "pi_factor": "measured split (6x numeric, 10x Python-level)" if shares is not None else PI_FACTOR,
        "pi_cores": pi_cores,
        "pi_cores_left": round(PI_CORES - pi_cores, 2),
        "pi_cores_at_10x": round(PI_FACTOR * here_cores, 2),
        "pi_cores_at_6x": round(PI_FACTOR_NUMERIC * here_cores, 2),
        "pi_loop_thread_cores": round(PI_FACTOR * loop_thread_ms / 1000.0, 2),
        "budget": check_budget(result, pi_cores, loop_thread_ms),
    }
