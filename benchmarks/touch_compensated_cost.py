"""Thread CPU per camera frame of touch with the projected light compensated, as `feelium bench board` runs it:
the rear frames the bench plays (320x240), the bench's projector calibration, a talking face on the skin (the
face-on experiment's wearer video through the daemon's renderer, 30 fps), each camera frame's light and spread
mixed by :class:`feelium.touch.projected.ExposureLight` and the pipeline fed with them.

    PYTHONPATH=$PWD python3 benchmarks/touch_compensated_cost.py [--loops 3] [--paced] [--profile] [--calls] [--detect-scale S] [--json FILE]

One OpenCV thread (the daemon's touch thread competes with the projector's pool: its own figure is the one that
counts). Reports ms per camera frame: ``predict`` (each new projector canvas to its light; with ``detect_scale``
< 1 at the detection size, and ``predict (fine windows)`` the fine pass's windows, inside ``pipeline``), ``mix`` (the exposure
mixes and spread), ``pipeline`` (``TouchPipeline.process``) and ``total``; ``--profile`` also splits the
pipeline's time by stage (timing wrappers: they add a few microseconds a call); ``--calls`` adds one more pass
under ``cProfile``, outside the timed ones, and reports the Python-level calls per frame (functions and builtins,
the interpreter's per-frame work) and the functions called most. The bench's frames hold no
projection, so this measures cost, not accuracy (the face-on experiment measures that). The first loop warms
up; each figure is the median over the later loops of their means. For an A/B run it from the older tree with
``PYTHONPATH`` pointing there, back to back.

``--paced`` feeds the frames at the camera's rate, as the daemon's touch thread gets them: before each frame it sleeps
until that frame's 1/30 s slot (caches go cold in between: on the 2-core VM a frame costs 1.5-1.7x its back-to-back
figure, 2026-11-27). Thread CPU is timed as without it; ``process_ms_per_frame`` adds the whole process's CPU over
each loop (``os.times``, user + system of every thread: OpenCV's pool included when it has one) per frame.
"""

from __future__ import annotations

import argparse
import cProfile
import inspect
import os
import pstats
import statistics
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from feelium.daemon.config import Config
from feelium.daemon.memory import tune_malloc
from feelium.lab.daemon.board import simulated_calibration
from feelium.lab.daemon.preloaded import rear_frames
from feelium.lab.touch.faceon import FaceScript, FaceVideo
from feelium.projector.canvaslight import CanvasLightPredictor
from feelium.projector.renderer import Renderer
from feelium.skin.projector_map import load_or_default
from feelium.touch import pipeline as pipeline_module
from feelium.touch.pipeline import TouchPipeline
from feelium.touch.projected import ExposureLight, ProjectorHistory, history_window_s
from feelium.lab.report import print_and_save

FPS = 30.0
SHOWN_OFFSET_S = 0.004  # the projector's frames are handed over a little after the camera's (unsynchronised clocks)

STAGES = {  # (owner, attribute) timed with --profile, charged to the name
    "compensate": ("response", "compensate"),
    "learn (sums + fit)": ("response", "learn"),
    "fit": ("response", "_fit"),
    "follow light": ("pipeline", "_follow_light"),
    "cut light/spread": ("pipeline", "_cut_light"),
    "prepare": ("pipeline", "_prepare"),
    "depth_uncertainty": ("module", "depth_uncertainty"),
    "spread_window": ("module", "spread_window"),
    "relative_depth": ("module", "relative_depth"),  # the coarse depth until session 25
    "depth_against": ("module", "depth_against"),  # the coarse depth since session 25 (its product made once)
    "usable mask": ("pipeline", "_usable"),  # since session 25 the gain's and follow light's mask, made once
    "refine (fine window)": ("pipeline", "_refine"),
    "find_candidates": ("module", "find_candidates"),
    "noise floor": ("module", "_noise_floor_map"),
    "reference update": ("reference", "update"),
    "tracker": ("tracker", "step"),
    "share learn": ("share", "learn"),
    # The share's map: made by share_map in older trees (coarse then reads its cache), by coarse since session 15 (a
    # candidate reads it at its point with share_at; share_map only for the probe's compensation).
    "share map": ("share", "share_map"),
    "share coarse": ("share", "coarse"),
    "share at point": ("share", "share_at"),
    "fine inputs": ("pipeline", "_fine_inputs"),
    "detail lesson": ("pipeline", "_learn_detail"),
}


FINE = "predict (fine windows)"  # the fine windows' light, of one canvas or of a mix


def _timed(fn: Callable[..., Any], name: str, sink: dict[str, float]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            sink[name] += time.thread_time() - start

    return wrapper


def _instrument(pipeline: TouchPipeline, sink: dict[str, float]) -> None:
    owners = {"response": pipeline.response, "pipeline": pipeline, "reference": pipeline.reference,
              "tracker": pipeline.tracker, "share": pipeline.projector_share}  # fmt: skip
    for name, (owner, attr) in STAGES.items():
        if owner == "module" and not hasattr(pipeline_module, attr):
            continue  # a stage an older tree does not have
        if owner == "module":
            setattr(pipeline_module, attr, _timed(getattr(pipeline_module, attr), name, sink))
        elif hasattr(owners[owner], attr):  # an older tree may not have it (the fine window)
            target = owners[owner]
            setattr(target, attr, _timed(getattr(target, attr), name, sink))


def _calls_per_frame(counter: cProfile.Profile, frames: int, top: int = 25) -> dict[str, Any]:
    """Python-level calls per frame in total and of the ``top`` functions called most (the counting pass's)."""
    stats = pstats.Stats(counter).stats  # type: ignore[attr-defined]
    calls = {f"{Path(file).name}:{line} {name}": row[1] for (file, line, name), row in stats.items()}
    most = sorted(calls.items(), key=lambda item: -item[1])[:top]
    return {
        "python_calls_per_frame": round(sum(calls.values()) / frames, 1),
        "most_called_per_frame": {name: round(n / frames, 1) for name, n in most},
    }


def _process_cpu() -> float:
    """The process's CPU time so far (user + system, every thread), in seconds."""
    times = os.times()
    return times.user + times.system


def _sleep_until(when: float) -> None:
    """Sleep until ``when`` (``time.perf_counter``'s clock); a frame that is already late starts at once."""
    wait = when - time.perf_counter()
    if wait > 0.0:
        time.sleep(wait)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loops", type=int, default=3, help="passes over the 6 s of frames (the first warms up)")
    parser.add_argument("--profile", action="store_true", help="split the pipeline's time by stage")
    parser.add_argument("--calls", action="store_true", help="count the Python calls per frame in one more pass")
    parser.add_argument("--paced", action="store_true", help="one frame every 1/30 s, as the camera delivers them")
    parser.add_argument("--json", help="write the figures here")
    parser.add_argument("--detect-scale", type=float, help="[touch] detect_scale (default: the config's)")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    config = Config()
    if args.detect_scale is not None:  # the frames stay at the working size: only the detection pass is scaled
        config = replace(config, touch=replace(config.touch, detect_scale=args.detect_scale))
    tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)
    size = (config.touch.width, config.touch.height)
    frames, roi = rear_frames(config.sim, size, FPS, 6.0)
    with tempfile.TemporaryDirectory() as scratch:
        path = simulated_calibration(config, Path(scratch))
        calibration = load_or_default(path, (config.projector.width, config.projector.height), None)
    renderer = Renderer(config.projector, calibration)
    source = Renderer(replace(config.projector, sensing_floor=0.0, fade_floor=0.0), calibration)
    video = FaceVideo(renderer, source, FaceScript(), 0.0)
    loops = max(2, args.loops)
    passes = loops + 1 if args.calls else loops  # the counting pass runs last, outside the timed ones
    canvases = [video.shown(k)[1] for k in range(len(frames) * passes + 2)]  # rendered outside the timing
    # As the daemon builds it: over the pipeline's ROI (older trees predict the whole frame).
    boxed = "box" in inspect.signature(CanvasLightPredictor).parameters
    box = {"box": roi} if boxed else {}
    pipeline = TouchPipeline(config.touch, size, roi)
    # With detect_scale < 1 (trees that have it): on the detection grid, the fine pass's windows at the working size.
    grids = getattr(pipeline, "light_grids", None)
    window = mix_window = None
    if grids is None:
        predictor = CanvasLightPredictor(config.projector, calibration, size, **box)
    else:
        (coarse_size, coarse_box), fine_grid = grids.coarse, grids.fine
        finer = None
        if fine_grid is not None:  # as the daemon builds them (feelium.touch.service)
            finer = CanvasLightPredictor(config.projector, calibration, fine_grid[0], box=fine_grid[1])
            window = finer.window
            mix_window = getattr(finer, "window_of_mix", None)  # older trees predict each frame's window apart
        predictor = CanvasLightPredictor(
            config.projector, calibration, coarse_size, box=coarse_box, average_of=grids.average_of, finer=finer
        )
    cpu: dict[str, float] = defaultdict(float)

    recycles = "out" in inspect.signature(predictor.gain).parameters  # older trees: predict(canvas) only

    def predict(canvas: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        start = time.thread_time()
        try:
            return predictor.gain(canvas, out) if recycles else predictor.gain(canvas)
        finally:
            cpu["predict"] += time.thread_time() - start

    if args.profile:
        _instrument(pipeline, cpu)
    if grids is None:
        exposure = ExposureLight(predict, config.touch)
        fine = {}
    else:
        by_mix = {"mixed_window": _timed(mix_window, FINE, cpu)} if mix_window is not None else {}  # as the daemon's service
        exposure = ExposureLight(predict, config.touch, _timed(window, FINE, cpu) if window is not None else None, **by_mix)
        fine = {"fine_light": exposure.window}
    history = ProjectorHistory(history_window_s(config.touch))
    per_loop: list[dict[str, float]] = []
    shown = 0
    counter = cProfile.Profile()
    process_ms: list[float] = []
    for loop in range(passes):
        cpu.clear()
        counting = loop == loops
        begun, process_start = time.perf_counter(), _process_cpu()
        for i, frame in enumerate(frames):
            t = (loop * len(frames) + i) / FPS
            if args.paced:
                _sleep_until(begun + (i + 1) / FPS)
            while shown / FPS + SHOWN_OFFSET_S <= t:
                history.record(shown / FPS + SHOWN_OFFSET_S, shown + 1, canvases[shown])
                shown += 1
            if counting:
                counter.enable()
            start = time.thread_time()
            mixed = exposure(history.frames(), t)
            middle = time.thread_time()
            if mixed is None:
                pipeline.process(t, frame)
            else:
                pipeline.process(t, frame, projected_light=mixed[0], projected_spread=mixed[1], **fine)
            end = time.thread_time()
            if counting:
                counter.disable()
            cpu["exposure light"] += middle - start
            cpu["pipeline"] += end - middle
        if not counting:
            process_ms.append(1000.0 * (_process_cpu() - process_start) / len(frames))
        row = {name: 1000.0 * value / len(frames) for name, value in cpu.items()}
        row["mix"] = row["exposure light"] - row.get("predict", 0.0)
        row["total"] = row["exposure light"] + row["pipeline"]
        if not counting:
            per_loop.append(row)
    later = per_loop[1:]
    report = {
        "frames_per_loop": len(frames),
        "loops": loops,
        "response_fits": getattr(pipeline.response, "fits", pipeline.response.updates),
        "response_updates": pipeline.response.updates,
        "projector_frames_predicted": exposure.predicted,
        "ms_per_frame": {k: round(statistics.median(r.get(k, 0.0) for r in later), 3) for k in sorted(later[0])},
        "total_by_loop": [round(r["total"], 3) for r in per_loop],
        "paced": args.paced,
        # Everything the process ran in each later loop, per frame: the timed work, the history's bookkeeping and
        # any other thread (at os.times' resolution, 10 ms a loop: ~0.06 ms a frame).
        "process_ms_per_frame": round(statistics.median(process_ms[1:]), 3),
        "process_ms_by_loop": [round(v, 3) for v in process_ms],
    }
    if args.calls:
        report.update(_calls_per_frame(counter, len(frames)))
    print_and_save(report, args.json, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
