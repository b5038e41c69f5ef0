"""`feelium bench thermal`: the vectorised decoder against the per-pixel baseline, in one run.

Both decode the same raw frames (the simulated vendor device looking at a
scene with a warm hand) with the same calibration; a "frame" is both
sub-pages, i.e. all 768 pixels. Reported: median and 95th percentile of each,
their ratio, and the largest disagreement between them (which must be ~0).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from feelium.thermal.calibration import extract_calibration
from feelium.thermal.decoder import Decoder
from feelium.thermal.sim_device import SimMlx90640, VirtualClock
from feelium.lab.thermal.per_pixel import per_pixel_temperatures
from feelium.thermal.vendor_eeprom import vendor_eeprom
from feelium.lab.timing import time_calls


def _frames(count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` pairs of raw sub-page frames (0 then 1) from the simulated vendor device."""
    from feelium.sim.thermal import ThermalSceneRenderer, WarmBody

    renderer = ThermalSceneRenderer(np.random.default_rng(0), 22.0)
    clock = VirtualClock()
    sensor = SimMlx90640(lambda t: renderer.frame(t, [WarmBody(0.4, 0.5, 50.0, 0.15)]), clock=clock, sleep=clock.sleep)
    pairs = []
    for _ in range(count):
        pair = []
        for subpage in (0, 1):
            sensor.ram = sensor.raw_subpage(subpage, renderer.frame(clock(), [WarmBody(0.4, 0.5, 50.0, 0.15)]))
            status = 0x0008 | subpage
            pair.append(np.concatenate([sensor.ram, np.array([status, sensor.control], dtype=np.uint16)]))
            clock.sleep(0.125)
        pairs.append((pair[0], pair[1]))
    return pairs


def run_bench(repeats: int = 100, baseline_repeats: int = 15) -> dict[str, Any]:
    """Time both implementations on the same frames; a JSON-ready result.

    Per frame: CPU time of this thread (the headline: it stays meaningful on a
    loaded machine) and wall time beside it, via :func:`feelium.lab.timing.time_calls`.
    """
    pairs = _frames(max(repeats, baseline_repeats))
    cal = extract_calibration(vendor_eeprom())
    decoder = Decoder(cal)
    for a, b in pairs[:3]:  # warm-up (imports, caches)
        decoder.decode(a)
        decoder.decode(b)
    as_lists = [(a.tolist(), b.tolist()) for a, b in pairs[:baseline_repeats]]  # how pure-Python drivers hold words

    def vectorised(i: int) -> None:
        decoder.decode(pairs[i][0])
        decoder.decode(pairs[i][1])

    def per_pixel(i: int) -> None:
        per_pixel_temperatures(cal, as_lists[i][0])
        per_pixel_temperatures(cal, as_lists[i][1])

    vec = {**time_calls(vectorised, repeats), "runs": repeats}
    base = {**time_calls(per_pixel, baseline_repeats), "runs": baseline_repeats}
    worst = 0.0
    for a, b in pairs[:baseline_repeats]:
        for raw in (a, b):
            ref = np.asarray(per_pixel_temperatures(cal, raw.tolist()))
            worst = max(worst, float(np.nanmax(np.abs(decoder.decode(raw).celsius - ref))))
    return {
        "bench": "thermal",
        "unit": "one full frame (768 pixels = 2 sub-pages); ms of thread CPU time, wall time beside",
        "vectorised": vec,
        "per_pixel_python": base,
        "speedup_median": base["median_ms"] / vec["median_ms"],
        "speedup_wall_median": base["wall_median_ms"] / vec["wall_median_ms"],
        "max_abs_difference_c": worst,
    }


def format_table(result: dict[str, Any]) -> str:
    rows = [("vectorised (numpy)", result["vectorised"]), ("per-pixel Python", result["per_pixel_python"])]
    lines = [f"{'implementation':<22}{'CPU median ms':>14}{'CPU p95 ms':>12}{'wall median ms':>16}{'runs':>6}"]
    for name, r in rows:
        lines.append(f"{name:<22}{r['median_ms']:>14.3f}{r['p95_ms']:>12.3f}{r['wall_median_ms']:>16.3f}{r['runs']:>6}")
    lines.append(
        f"speed-up (CPU median): {result['speedup_median']:.1f}x (wall: {result['speedup_wall_median']:.1f}x); "
        f"max |difference| {result['max_abs_difference_c']:.2e} degC"
    )
    return "\n".join(lines)


__all__ = ["format_table", "run_bench"]
