"""``feelium bench daemon``: the whole daemon in sim mode, measured from inside its own process.

Reports resident memory (sampled each second), CPU time per rear-camera frame
and dropped frames. The baseline, measured in the same run before the daemon
starts, is the touch pipeline alone on frames of the same simulated scene
(and the scene's rendering alone), so the ratio shows what running it as a
service among the others costs on top of the algorithm.
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from feelium.config import Config, load_config
from feelium.daemon.memory import limit_malloc_arenas
from feelium.daemon.runner import run_daemon, with_overrides
from feelium.daemon.sdnotify import Notifier
from feelium.hub import Hub

BASELINE_FRAMES = 150


def resident_mb() -> float:
    """This process's resident set size in MB (Linux /proc; 0 where unavailable)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def cpu_seconds() -> float:
    times = os.times()
    return times.user + times.system


def _percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values, dtype=np.float64), q)) if values else float("nan")


def baseline(config: Config, frames: int = BASELINE_FRAMES) -> dict[str, float]:
    """CPU ms per frame of rendering the sim scene and of the touch pipeline alone, one thread, nothing else running."""
    from feelium.sim.live import LiveRearScene
    from feelium.touch.pipeline import TouchPipeline

    scene = LiveRearScene(config.sim, width=config.touch.width, height=config.touch.height)
    period = 1.0 / config.rear_camera.fps
    render_ms, images = [], []
    for i in range(frames):
        start = time.thread_time()
        images.append(scene.frame(i * period))
        render_ms.append(1000.0 * (time.thread_time() - start))
    pipeline = TouchPipeline(config.touch, (config.touch.width, config.touch.height), scene.roi)
    pipeline_ms = []
    for i, image in enumerate(images):
        start = time.thread_time()
        pipeline.process(i * period, image)
        pipeline_ms.append(1000.0 * (time.thread_time() - start))
    return {
        "render_ms_median": statistics.median(render_ms),
        "render_ms_p95": _percentile(render_ms, 95),
        "pipeline_ms_median": statistics.median(pipeline_ms),
        "pipeline_ms_p95": _percentile(pipeline_ms, 95),
    }


async def _measure(config: Config, seconds: float) -> dict[str, Any]:
    hub = Hub()
    stop = asyncio.Event()
    samples: list[dict[str, float]] = []
    holder: dict[str, Any] = {}

    async def sampler() -> None:
        while "supervisor" not in holder:
            await asyncio.sleep(0.01)
        await asyncio.sleep(1.0)  # let every service open its devices before measuring
        start = time.monotonic()
        while time.monotonic() - start < seconds:
            touch = hub.health()["services"].get("touch", {})
            samples.append(
                {
                    "t": time.monotonic() - start,
                    "rss_mb": resident_mb(),
                    "cpu_s": cpu_seconds(),
                    "frames": float(touch.get("frames", 0)),
                    "dropped": float(touch.get("dropped_frames", 0)),
                }
            )
            await asyncio.sleep(1.0)
        holder["final"] = hub.health()
        samples.append(
            {"t": time.monotonic() - start, "rss_mb": resident_mb(), "cpu_s": cpu_seconds(),
             "frames": float(holder["final"]["services"].get("touch", {}).get("frames", 0)),
             "dropped": float(holder["final"]["services"].get("touch", {}).get("dropped_frames", 0))}
        )
        stop.set()

    task = asyncio.create_task(sampler())
    await run_daemon(config, stop=stop, hub=hub, notifier=Notifier({}), on_started=lambda h, s: holder.update(supervisor=s))
    await task
    return {"samples": samples, "final": holder["final"]}


def bench_daemon(config: Config, seconds: float) -> dict[str, Any]:
    """Baseline, then the daemon for ``seconds``; every number in one dict."""
    config = with_overrides(config, sim=True)
    config = dataclasses.replace(config, http=dataclasses.replace(config.http, port=0))  # never clash with a running daemon
    arenas_capped = limit_malloc_arenas(config.daemon.malloc_arenas)  # as `feelium run` does
    rss_idle = resident_mb()
    base = baseline(config)
    measured = asyncio.run(_measure(config, seconds))
    samples = measured["samples"]
    final = measured["final"]
    first, last = samples[0], samples[-1]
    frames = last["frames"] - first["frames"]
    cpu = last["cpu_s"] - first["cpu_s"]
    wall = last["t"] - first["t"]
    per_second_ms = [
        1000.0 * (b["cpu_s"] - a["cpu_s"]) / (b["frames"] - a["frames"])
        for a, b in zip(samples, samples[1:])
        if b["frames"] > a["frames"]
    ]
    rss = [s["rss_mb"] for s in samples]
    touch = final["services"].get("touch", {})
    cpu_per_frame = 1000.0 * cpu / frames if frames else float("nan")
    return {
        "seconds": round(wall, 2),
        "cpus": os.cpu_count(),
        "rss_mb_before_start": round(rss_idle, 1),
        "rss_mb_median": round(statistics.median(rss), 1),
        "rss_mb_p95": round(_percentile(rss, 95), 1),
        "rss_mb_max": round(max(rss), 1),
        "rss_goal_mb": 150.0,
        "malloc_arenas": config.daemon.malloc_arenas if arenas_capped else "glibc default",
        "rear_frames": int(frames),
        "rear_fps": round(frames / wall, 2) if wall > 0 else 0.0,
        "rear_fps_target": config.rear_camera.fps,
        "process_cpu_percent_of_one_core": round(100.0 * cpu / wall, 1) if wall > 0 else 0.0,
        "process_cpu_ms_per_rear_frame": round(cpu_per_frame, 2),
        "process_cpu_ms_per_rear_frame_median_1s": round(statistics.median(per_second_ms), 2) if per_second_ms else None,
        "process_cpu_ms_per_rear_frame_p95_1s": round(_percentile(per_second_ms, 95), 2) if per_second_ms else None,
        "touch_worker_ms_per_frame": touch.get("ms_per_frame"),
        "dropped_rear_frames": int(last["dropped"] - first["dropped"]),
        "bad_rear_frames": touch.get("bad_frames"),
        "bus_dropped": final.get("bus", {}).get("dropped"),
        "services": {name: entry.get("state") for name, entry in final["services"].items()},
        "baseline": {k: round(v, 3) for k, v in base.items()},
        "ratio_cpu_per_frame_vs_pipeline_alone": round(cpu_per_frame / base["pipeline_ms_median"], 2)
        if base["pipeline_ms_median"] > 0 else None,
        "ratio_cpu_per_frame_vs_render_plus_pipeline": round(
            cpu_per_frame / (base["pipeline_ms_median"] + base["render_ms_median"]), 2
        ) if base["pipeline_ms_median"] + base["render_ms_median"] > 0 else None,
    }


def format_table(result: dict[str, Any]) -> str:
    b = result["baseline"]
    rows = [
        ("resident memory, MB (median / p95 / max)", f"{result['rss_mb_median']} / {result['rss_mb_p95']} / {result['rss_mb_max']}  (goal <= {result['rss_goal_mb']:.0f}; {result['rss_mb_before_start']} before start; malloc arenas: {result['malloc_arenas']})"),
        ("rear frames processed (fps / target)", f"{result['rear_frames']} ({result['rear_fps']} / {result['rear_fps_target']})"),
        ("dropped rear frames (newest wins)", f"{result['dropped_rear_frames']}"),
        ("bad rear frames / bus drops", f"{result['bad_rear_frames']} / {result['bus_dropped']}"),
        ("process CPU, % of one core", f"{result['process_cpu_percent_of_one_core']}"),
        ("process CPU ms per rear frame (all / 1 s median / p95)", f"{result['process_cpu_ms_per_rear_frame']} / {result['process_cpu_ms_per_rear_frame_median_1s']} / {result['process_cpu_ms_per_rear_frame_p95_1s']}"),
        ("touch worker wall ms per frame", f"{result['touch_worker_ms_per_frame']}"),
        ("baseline: pipeline alone CPU ms/frame (median / p95)", f"{b['pipeline_ms_median']} / {b['pipeline_ms_p95']}"),
        ("baseline: sim render alone CPU ms/frame (median / p95)", f"{b['render_ms_median']} / {b['render_ms_p95']}"),
        ("ratio: daemon CPU per frame / pipeline alone", f"{result['ratio_cpu_per_frame_vs_pipeline_alone']}"),
        ("ratio: daemon CPU per frame / (render + pipeline)", f"{result['ratio_cpu_per_frame_vs_render_plus_pipeline']}"),
    ]
    width = max(len(r[0]) for r in rows)
    lines = [f"feelium bench daemon: {result['seconds']} s in sim mode on {result['cpus']} CPUs"]
    lines += [f"  {name.ljust(width)}  {value}" for name, value in rows]
    lines.append("  services: " + ", ".join(f"{k}={v}" for k, v in result["services"].items()))
    return "\n".join(lines)


def bench_daemon_command(args: argparse.Namespace) -> int:
    import logging

    from feelium.daemon.journal import setup_logging

    setup_logging(logging.WARNING)
    if not args.seconds > 0:
        print("feelium bench daemon: --seconds must be positive", file=sys.stderr)
        return 2
    result = bench_daemon(load_config(args.config), args.seconds)
    print(format_table(result))
    text = json.dumps(result, indent=1)
    if args.json:
        Path(args.json).write_text(text + "\n", encoding="utf-8")
    else:
        print(text)
    return 0
