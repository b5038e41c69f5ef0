"""`feelium bench thermal`: the vectorised decoder against the per-pixel baseline, in one run.

Both decode the same raw frames (the emulated vendor device looking at a
scene with a warm hand) with the same calibration; a "frame" is both
sub-pages, i.e. all 768 pixels. Reported: median and 95th percentile of each,
their ratio, and the largest disagreement between them (which must be ~0).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from feelium.thermal.calibration import extract_calibration
from feelium.thermal.decoder import Decoder
from feelium.thermal.emulator import Mlx90640Emulator, VirtualClock
from feelium.thermal.reference import reference_temperatures
from feelium.thermal.vendor_eeprom import vendor_eeprom


def _frames(count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` pairs of raw sub-page frames (0 then 1) from the emulated vendor device."""
    from feelium.sim.thermal import ThermalSceneRenderer, WarmBody

    renderer = ThermalSceneRenderer(np.random.default_rng(0), 22.0)
    clock = VirtualClock()
    emu = Mlx90640Emulator(lambda t: renderer.frame(t, [WarmBody(0.4, 0.5, 50.0, 0.15)]), clock=clock, sleep=clock.sleep)
    pairs = []
    for _ in range(count):
        pair = []
        for subpage in (0, 1):
            emu.ram = emu.raw_subpage(subpage, renderer.frame(clock(), [WarmBody(0.4, 0.5, 50.0, 0.15)]))
            status = 0x0008 | subpage
            pair.append(np.concatenate([emu.ram, np.array([status, emu.control], dtype=np.uint16)]))
            clock.sleep(0.125)
        pairs.append((pair[0], pair[1]))
    return pairs


def _percentiles(seconds: list[float]) -> dict[str, float]:
    ms = np.asarray(seconds) * 1000.0
    return {"median_ms": float(np.median(ms)), "p95_ms": float(np.percentile(ms, 95)), "runs": len(ms)}


def run_bench(repeats: int = 100, baseline_repeats: int = 15) -> dict[str, Any]:
    """Time both implementations on the same frames; a JSON-ready result."""
    pairs = _frames(max(repeats, baseline_repeats))
    cal = extract_calibration(vendor_eeprom())
    decoder = Decoder(cal)
    for a, b in pairs[:3]:  # warm-up (imports, caches)
        decoder.decode(a)
        decoder.decode(b)
    fast: list[float] = []
    for a, b in pairs[:repeats]:
        t0 = time.perf_counter()
        decoder.decode(a)
        decoder.decode(b)
        fast.append(time.perf_counter() - t0)
    slow: list[float] = []
    worst = 0.0
    for a, b in pairs[:baseline_repeats]:
        la, lb = a.tolist(), b.tolist()
        t0 = time.perf_counter()
        ra = reference_temperatures(cal, la)
        rb = reference_temperatures(cal, lb)
        slow.append(time.perf_counter() - t0)
        for raw, ref in ((a, ra), (b, rb)):
            got = decoder.decode(raw).celsius
            diff = np.abs(got - np.asarray(ref))
            worst = max(worst, float(np.nanmax(diff)))
    vec, base = _percentiles(fast), _percentiles(slow)
    return {
        "bench": "thermal",
        "unit": "one full frame (768 pixels = 2 sub-pages)",
        "vectorised": vec,
        "per_pixel_python": base,
        "speedup_median": base["median_ms"] / vec["median_ms"],
        "max_abs_difference_c": worst,
    }


def format_table(result: dict[str, Any]) -> str:
    rows = [("vectorised (numpy)", result["vectorised"]), ("per-pixel Python", result["per_pixel_python"])]
    lines = [f"{'implementation':<22}{'median ms':>12}{'p95 ms':>10}{'runs':>6}"]
    for name, r in rows:
        lines.append(f"{name:<22}{r['median_ms']:>12.3f}{r['p95_ms']:>10.3f}{r['runs']:>6}")
    lines.append(f"speed-up (median): {result['speedup_median']:.1f}x; max |difference| {result['max_abs_difference_c']:.2e} degC")
    return "\n".join(lines)


__all__ = ["format_table", "run_bench"]
