"""``feelium bench daemon``: the whole daemon in sim mode, measured from inside its own process.

Reports resident memory (peak, and steady = median over the run's second
half), CPU time per rear-camera frame and per thread group, and each
service's frames and drops. The baseline, measured in the same run after the
daemon stopped (so its buffers do not count in the daemon's memory), is the
touch pipeline alone on frames of the same simulated scene (and the scene's
rendering alone), so the ratio shows what running the whole blimp costs per
frame on top of the algorithm. With ``--per-service-seconds`` each service
also runs alone in a fresh process, for what it adds to resident memory.
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import os
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from feelium.daemon.config import Config, load_config
from feelium.daemon.assembly import SERVICES
from feelium.daemon.memory import tune_malloc
from feelium.daemon.runner import run_daemon, with_overrides
from feelium.daemon.sdnotify import Notifier
from feelium.hub import Hub
from feelium.lab.report import emit_report

RSS_GOAL_MB = 150.0
PAGE_BYTES = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096
BASELINE_FRAMES = 150


def memory_mb() -> dict[str, float]:
    """This process's resident memory in MB: total, anonymous (heap, arrays) and file-backed (libraries); Linux only."""
    out = {"rss": 0.0, "anon": 0.0, "file": 0.0}
    keys = {"VmRSS": "rss", "RssAnon": "anon", "RssFile": "file"}
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            key, _, value = line.partition(":")
            if key in keys:
                out[keys[key]] = int(value.split()[0]) / 1024.0
    except OSError:
        pass
    return out


def resident_mb() -> float:
    """This process's resident memory in MB (``VmRSS``), from ``/proc/self/statm``: one line, where ``status`` is
    ~55 for the kernel to format and Python to parse (a probe reads it on the daemon's loop while it runs); 0.0
    where there is no ``/proc``."""
    try:
        with open("/proc/self/statm", "rb") as statm:
            return int(statm.read().split()[1]) * PAGE_BYTES / 2**20
    except OSError:
        return 0.0


def restart_peak_rss() -> bool:
    """Restart the kernel's resident high-water mark (``VmHWM``) of this process from what is resident now (writing
    5 to ``/proc/self/clear_refs``, Linux 4.0 on); False where that is not allowed. A peak sampled every 0.5 s on the
    loop misses what a start-up allocates and frees between two samples, or while it blocks the loop; the kernel's
    mark misses nothing."""
    try:
        with open("/proc/self/clear_refs", "w") as clear_refs:
            clear_refs.write("5")
        return True
    except OSError:
        return False


def peak_rss_mb() -> float | None:
    """This process's resident high-water mark in MB (``VmHWM``) since it started or :func:`restart_peak_rss`;
    ``None`` where there is no ``/proc``."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def cpu_seconds() -> float:
    times = os.times()
    return times.user + times.system


def thread_group(name: str) -> str:
    """Which part of the daemon a thread works for, from its Python name."""
    if name == "MainThread":
        return "event loop (all services' async code)"
    if name.startswith(("rear-camera", "touch-pipeline")):
        return "touch (rear camera + pipeline threads)"
    if name.startswith("front-camera"):
        return "front_camera (camera thread)"
    if name.startswith("asyncio_") or name.startswith("feelium-worker"):
        return "shared pool (projector, thermal, flight, http encode)"
    return "other threads (OpenCV pool, libraries)"


def thread_cpu_seconds() -> dict[int, float]:
    """CPU seconds of each of this process's threads, by kernel thread id (Linux /proc)."""
    tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    out: dict[int, float] = {}
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return out
    for tid in tids:
        try:
            fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # the thread ended meanwhile
        out[int(tid)] = (int(fields[11]) + int(fields[12])) / tick  # utime, stime
    return out


def cpu_by_group(before: dict[int, float], after: dict[int, float], names: dict[int, str]) -> dict[str, float]:
    """CPU seconds spent between two snapshots, summed per thread group (threads that ended are lost)."""
    groups: dict[str, float] = {}
    for tid, seconds in after.items():
        group = thread_group(names.get(tid, ""))
        groups[group] = groups.get(group, 0.0) + seconds - before.get(tid, 0.0)
    return groups


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


COUNTERS = ("frames", "cycles", "captured_chunks")  # what each service calls its unit of work
DROPS = ("dropped_frames", "overruns", "playback_dropped_ms")


def _first(entry: dict[str, Any], keys: tuple[str, ...]) -> tuple[str | None, float]:
    for key in keys:
        if isinstance(entry.get(key), (int, float)):
            return key, float(entry[key])
    return None, 0.0


def service_rows(first: dict[str, Any], last: dict[str, Any], wall: float) -> dict[str, dict[str, Any]]:
    """Per service over the measured window: state, work done and its rate, drops, restarts."""
    rows = {}
    for name, end in last["services"].items():
        start = first["services"].get(name, {})
        unit, done = _first(end, COUNTERS)
        drop_key, dropped = _first(end, DROPS)
        rows[name] = {
            "state": end.get("state"),
            "unit": unit,
            "count": int(done - _first(start, COUNTERS)[1]) if unit else None,
            "rate_per_s": round((done - _first(start, COUNTERS)[1]) / wall, 2) if unit and wall > 0 else None,
            "drops_key": drop_key,
            "drops": round(dropped - _first(start, DROPS)[1], 1) if drop_key else None,
            "restarts": int(end.get("restarts", 0)) - int(start.get("restarts", 0)),
        }
    return rows


async def _measure(config: Config, seconds: float) -> dict[str, Any]:
    hub = Hub()
    stop = asyncio.Event()
    samples: list[dict[str, Any]] = []
    holder: dict[str, Any] = {}

    def sample(start: float) -> dict[str, Any]:
        touch = hub.health()["services"].get("touch", {})
        return {
            "t": time.monotonic() - start,
            "memory": memory_mb(),
            "cpu_s": cpu_seconds(),
            "frames": float(touch.get("frames", 0)),
            "dropped": float(touch.get("dropped_frames", 0)),
        }

    async def sampler() -> None:
        while "supervisor" not in holder:
            await asyncio.sleep(0.01)
        await asyncio.sleep(1.0)  # let every service open its devices before measuring
        start = time.monotonic()
        holder["first"] = hub.health()
        holder["threads_before"] = thread_cpu_seconds()
        while time.monotonic() - start < seconds:
            samples.append(sample(start))
            await asyncio.sleep(1.0)
        samples.append(sample(start))
        holder["threads_after"] = thread_cpu_seconds()
        holder["thread_names"] = {t.native_id: t.name for t in threading.enumerate() if t.native_id is not None}
        holder["final"] = hub.health()
        stop.set()

    task = asyncio.create_task(sampler())
    await run_daemon(config, stop=stop, hub=hub, notifier=Notifier({}), on_started=lambda h, s: holder.update(supervisor=s))
    await task
    return {"samples": samples, **holder}


def _bench_config(config: Config) -> Config:
    config = with_overrides(config, sim=True)
    return dataclasses.replace(config, http=dataclasses.replace(config.http, port=0))  # never clash with a running daemon


def service_alone(part: str, seconds: float, config_file: str | None = None) -> dict[str, Any]:
    """Resident memory of a fresh daemon process running only ``part`` of the assembly (or ``none``) in sim mode."""
    code = (
        "import json, sys; from feelium.lab.daemon.bench import _alone_main; "
        "print(json.dumps(_alone_main(sys.argv[1], float(sys.argv[2]), sys.argv[3] or None)))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, part, str(seconds), config_file or ""],
        capture_output=True, text=True, timeout=seconds + 120, check=False,
    )
    if done.returncode != 0:
        return {"error": (done.stderr.strip().splitlines() or ["exit %d" % done.returncode])[-1]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def _alone_main(part: str, seconds: float, config_file: str | None) -> dict[str, Any]:
    config = _bench_config(load_config(config_file))
    tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)
    rss: list[float] = []

    async def main() -> None:
        stop = asyncio.Event()

        async def sampler() -> None:
            start = time.monotonic()
            while time.monotonic() - start < seconds:
                await asyncio.sleep(1.0)
                rss.append(resident_mb())
            stop.set()

        task = asyncio.create_task(sampler())
        builders = tuple((name, build) for name, build in SERVICES if name == part)
        await run_daemon(config, stop=stop, notifier=Notifier({}), builders=builders)
        await task

    asyncio.run(main())
    return {"rss_mb_steady": round(statistics.median(rss[len(rss) // 2 :]), 1), "rss_mb_max": round(max(rss), 1)}


def per_service_memory(seconds: float, config_file: str | None) -> dict[str, Any]:
    """Each part of the assembly alone in its own process, and what it adds over an empty daemon."""
    empty = service_alone("none", seconds, config_file)
    out: dict[str, Any] = {"(no service)": empty}
    for part, _ in SERVICES:
        alone = service_alone(part, seconds, config_file)
        if "rss_mb_steady" in alone and "rss_mb_steady" in empty:
            alone["adds_mb"] = round(alone["rss_mb_steady"] - empty["rss_mb_steady"], 1)
        out[part] = alone
    return out


def _load() -> float | None:
    return round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None


def bench_daemon(
    config: Config,
    seconds: float,
    *,
    per_service_seconds: float = 0.0,
    config_file: str | None = None,
    baseline_frames: int = BASELINE_FRAMES,
) -> dict[str, Any]:
    """The daemon for ``seconds``, then the baseline; every number in one dict."""
    config = _bench_config(config)
    malloc = tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)  # as `feelium run` does
    before = memory_mb()
    load_before = _load()
    measured = asyncio.run(_measure(config, seconds))
    load_after = _load()
    base = baseline(config, baseline_frames)
    samples = measured["samples"]
    first, last = samples[0], samples[-1]
    frames = last["frames"] - first["frames"]
    cpu = last["cpu_s"] - first["cpu_s"]
    wall = last["t"] - first["t"]
    per_second_ms = [
        1000.0 * (b["cpu_s"] - a["cpu_s"]) / (b["frames"] - a["frames"])
        for a, b in zip(samples, samples[1:])
        if b["frames"] > a["frames"]
    ]
    rss = [s["memory"]["rss"] for s in samples]
    steady = samples[len(samples) // 2 :]
    final = measured["final"]
    touch = final["services"].get("touch", {})
    cpu_per_frame = 1000.0 * cpu / frames if frames else float("nan")
    groups = cpu_by_group(measured["threads_before"], measured["threads_after"], measured["thread_names"])
    result: dict[str, Any] = {
        "seconds": round(wall, 2),
        "cpus": os.cpu_count(),
        "load_average_1min_before_after": [load_before, load_after],  # other processes on the machine skew CPU numbers
        "rss_mb_before_start": round(before["rss"], 1),
        "rss_mb_steady": round(statistics.median(rss[len(rss) // 2 :]), 1),
        "rss_mb_peak": round(max(rss), 1),
        "rss_mb_p95": round(_percentile(rss, 95), 1),
        "rss_anon_mb_steady": round(statistics.median(s["memory"]["anon"] for s in steady), 1),
        "rss_file_mb_steady": round(statistics.median(s["memory"]["file"] for s in steady), 1),
        "rss_goal_mb": RSS_GOAL_MB,
        "rss_mb_each_second": [round(value, 1) for value in rss],
        "malloc": malloc or "glibc defaults",
        "rear_frames": int(frames),
        "rear_fps": round(frames / wall, 2) if wall > 0 else 0.0,
        "rear_fps_target": config.rear_camera.fps,
        "process_cpu_percent_of_one_core": round(100.0 * cpu / wall, 1) if wall > 0 else 0.0,
        "process_cpu_ms_per_rear_frame": round(cpu_per_frame, 2),
        "process_cpu_ms_per_rear_frame_median_1s": round(statistics.median(per_second_ms), 2) if per_second_ms else None,
        "process_cpu_ms_per_rear_frame_p95_1s": round(_percentile(per_second_ms, 95), 2) if per_second_ms else None,
        "cpu_ms_per_rear_frame_by_thread_group": {
            group: round(1000.0 * value / frames, 2) if frames else None for group, value in sorted(groups.items())
        },
        "touch_worker_ms_per_frame": touch.get("ms_per_frame"),
        "dropped_rear_frames": int(last["dropped"] - first["dropped"]),
        "bad_rear_frames": touch.get("bad_frames"),
        "bus_dropped": final.get("bus", {}).get("dropped"),
        "services": service_rows(measured["first"], final, wall),
        "baseline": {k: round(v, 3) for k, v in base.items()},
        "ratio_cpu_per_frame_vs_pipeline_alone": round(cpu_per_frame / base["pipeline_ms_median"], 2)
        if base["pipeline_ms_median"] > 0 else None,
        "ratio_cpu_per_frame_vs_render_plus_pipeline": round(
            cpu_per_frame / (base["pipeline_ms_median"] + base["render_ms_median"]), 2
        ) if base["pipeline_ms_median"] + base["render_ms_median"] > 0 else None,
    }
    if per_service_seconds > 0:
        result["memory_alone"] = per_service_memory(per_service_seconds, config_file)
    return result


def format_table(result: dict[str, Any]) -> str:
    b = result["baseline"]
    rows = [
        ("resident memory MB, steady / peak", f"{result['rss_mb_steady']} / {result['rss_mb_peak']}  (goal <= {result['rss_goal_mb']:.0f}; {result['rss_mb_before_start']} before start)"),
        ("  of which anonymous / file-backed (libraries)", f"{result['rss_anon_mb_steady']} / {result['rss_file_mb_steady']}  (malloc: {result['malloc']})"),
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
    lines = [
        f"feelium bench daemon: {result['seconds']} s in sim mode on {result['cpus']} CPUs "
        f"(1 min load average before / after: {result['load_average_1min_before_after']})"
    ]
    lines += [f"  {name.ljust(width)}  {value}" for name, value in rows]
    lines.append("  CPU ms per rear frame by thread group:")
    for group, ms in result["cpu_ms_per_rear_frame_by_thread_group"].items():
        lines.append(f"    {group.ljust(width - 2)}  {ms}")
    lines.append("  services (state, work/s, drops, restarts):")
    for name, row in result["services"].items():
        work = f"{row['rate_per_s']} {row['unit']}/s" if row["unit"] else "-"
        drops = f"{row['drops']} {row['drops_key']}" if row["drops_key"] else "-"
        lines.append(f"    {name.ljust(14)} {str(row['state']).ljust(9)} {work.ljust(26)} {drops.ljust(26)} {row['restarts']}")
    if "memory_alone" in result:
        lines.append("  resident memory MB of each service alone in a fresh process (steady / peak / adds over none):")
        for name, row in result["memory_alone"].items():
            text = row.get("error") or f"{row['rss_mb_steady']} / {row['rss_mb_max']} / {row.get('adds_mb', '-')}"
            lines.append(f"    {name.ljust(14)} {text}")
    return "\n".join(lines)


def bench_daemon_command(args: argparse.Namespace) -> int:
    import logging

    from feelium.daemon.journal import setup_logging

    setup_logging(logging.WARNING)
    if not args.seconds > 0:
        print("feelium bench daemon: --seconds must be positive", file=sys.stderr)
        return 2
    result = bench_daemon(
        load_config(args.config), args.seconds, per_service_seconds=args.per_service_seconds, config_file=args.config
    )
    emit_report(format_table(result), result, args.json)
    return 0
