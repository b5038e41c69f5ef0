"""`feelium bench touch`: speed against accuracy of the touch pipeline, with its plain baseline.

Every variant sees the same decoded frames of the same labelled dataset, one
recording at a time and interleaved (so a change in machine load hits every
variant alike), and is scored exactly as `feelium eval` scores it. The
baseline is the same algorithm done the plain way: float64, the whole camera
frame at camera resolution, no ROI cut (`TouchPipeline(plain=True)`).

Time is per frame, pipeline only (decoding excluded), on one core (OpenCV's
thread pool is set to one thread for the run): the calling thread's CPU time
is the headline figure, because it stays meaningful on a loaded machine; wall
time is reported beside it.

With ``--by-condition`` (datasets from ``feelium simulate condition``, or laid
out one folder per condition) the same table is also given for each
condition's recordings alone, with what the median frame would leave of the
board's 30 fps at the Pi projection's 10x (issue 17: the extra work of the
projected-light prediction must keep the touch loop at the camera's rate).

A recording with its projector stream is compensated as ``eval`` does it, and
the prediction of its light is timed apart (``light_cpu_ms_per_frame``) and
counted in the Pi's frame rate: ``pi_fps_at_10x`` is the frame rate of the
pipeline *and* the prediction. That prediction is replay's, from the recorded
full projector frames; the daemon predicts from its smaller skin canvases
(docs/performance.md), so it is an upper bound on the daemon's.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from feelium.daemon.config import load_config
from feelium.projector.config import ProjectorConfig
from feelium.recording import Recording, RecordingError, find_recordings
from feelium.lab.daemon.projection import PI_FACTOR
from feelium.lab.touch.commands import condition_of, scoring_input
from feelium.touch.config import TouchConfig
from feelium.lab.touch.evaluate import ClipData, TrialData, build_report
from feelium.lab.touch.recorded_light import recorded_light
from feelium.lab.touch.replay import replay_recording

RESOLUTIONS = ((640, 480), (320, 240), (160, 120))


@dataclass
class Variant:
    """One way of running the pipeline, and what it produced over the dataset."""

    name: str
    config: TouchConfig
    plain: bool = False
    cpu: list[np.ndarray] = field(default_factory=list)
    wall: list[np.ndarray] = field(default_factory=list)
    light: list[np.ndarray] = field(default_factory=list)  # the predicted light's CPU time per frame (0: none)
    trials: list[TrialData] = field(default_factory=list)
    clips: list[ClipData] = field(default_factory=list)
    by_condition: dict[str, Variant] = field(default_factory=dict)

    def add(self, cpu: np.ndarray, wall: np.ndarray, light: np.ndarray, item: TrialData | ClipData) -> None:
        self.cpu.append(cpu)
        self.wall.append(wall)
        self.light.append(light)
        (self.clips if isinstance(item, ClipData) else self.trials).append(item)  # type: ignore[arg-type]

    def of_condition(self, condition: str) -> Variant:
        """The same variant holding one condition's recordings only (made on first use)."""
        if condition not in self.by_condition:
            self.by_condition[condition] = Variant(self.name, self.config, self.plain)
        return self.by_condition[condition]


def build_variants(config: TouchConfig, resolutions: tuple[tuple[int, int], ...] = RESOLUTIONS) -> list[Variant]:
    """The plain float64 full-frame baseline first, then the pipeline at each working resolution."""
    variants = [Variant("plain float64 full frame", config, plain=True)]
    for w, h in resolutions:
        variants.append(Variant(f"ROI float32 {w}x{h}", replace(config, width=w, height=h)))
    return variants


def run_variants(root: Path, variants: list[Variant], *, progress: bool = False, by_condition: bool = False) -> dict[str, tuple[int, int]]:
    """Replay every labelled recording under ``root`` through every variant (decoded once, interleaved).

    Returns each condition's camera size (one entry, ``"."``, without ``by_condition``)."""
    paths = find_recordings(root)
    sizes: dict[str, tuple[int, int]] = {}
    for index, path in enumerate(paths, start=1):
        recording = Recording(path)
        if recording.labels is None:
            continue
        try:
            recorded_light(recording, root, ProjectorConfig(), variants[0].config)  # its map is there (or no stream)
        except RecordingError as exc:
            print(f"feelium bench touch: skipped: {exc}", file=sys.stderr)
            continue
        condition = condition_of(root, recording) if by_condition else "."
        sizes.setdefault(condition, (recording.meta.camera.width, recording.meta.camera.height))
        frames = list(recording.frames(gray=True))
        for variant in variants:
            # a recording with its projector stream is replayed as eval replays it: the light predicted and divided
            # out (the division is timed with the pipeline; the prediction is not, as in eval)
            light = recorded_light(recording, root, ProjectorConfig(), variant.config)
            result = replay_recording(recording, variant.config, plain=variant.plain, frames=iter(frames), light=light)
            item = scoring_input(root, result)
            timed = (result.cpu_seconds_per_frame, result.seconds_per_frame, result.light_cpu_seconds_per_frame)
            variant.add(*timed, item)
            if by_condition:
                variant.of_condition(condition).add(*timed, item)
        if progress:
            print(f"[{index}/{len(paths)}] {path}", file=sys.stderr)
    return sizes


def _ms(values: list[np.ndarray]) -> dict[str, float | None]:
    arr = 1000.0 * np.concatenate(values) if values else np.zeros(0)
    if arr.size == 0:
        return {"median": None, "p95": None}
    return {"median": float(np.median(arr)), "p95": float(np.percentile(arr, 95))}


def summarise(root: Path, variants: list[Variant], frame_size: tuple[int, int]) -> dict[str, Any]:
    """The bench report: per variant, ms per frame (CPU and wall), F1, localisation, anchoring AUC, speed-up, and
    the frame rate one Pi core would hold at the projection's factor (``pi_fps_at_10x``: the camera's 30 needs
    >= 30)."""
    rows = []
    for variant in variants:
        if variant.plain:
            width, height = frame_size
        else:
            width, height = variant.config.width, variant.config.height
        report = build_report(str(root), variant.trials, variant.clips, np.zeros(0), width, height)
        error = report["localisation"]["error_px"]
        rows.append(
            {
                "variant": variant.name,
                "plain": variant.plain,
                "width": width,
                "height": height,
                "frames": int(sum(v.size for v in variant.cpu)),
                "cpu_ms_per_frame": _ms(variant.cpu),
                "wall_ms_per_frame": _ms(variant.wall),
                "light_cpu_ms_per_frame": _ms(variant.light),
                "f1": report["trials"]["f1"],
                "precision": report["trials"]["precision"],
                "recall": report["trials"]["recall"],
                "localisation_error_px_median": error["median"] if error else None,
                "localisation_error_px_p95": error["p95"] if error else None,
                "anchoring_auc": report["sustained"]["auc"],
            }
        )
        # Pipeline and prediction frame by frame (the same frames, in the same order).
        with_light = _ms([cpu + light for cpu, light in zip(variant.cpu, variant.light)])["median"]
        rows[-1]["pi_fps_at_10x"] = round(1000.0 / (PI_FACTOR * with_light), 1) if with_light else None
    base = rows[0]["cpu_ms_per_frame"]["median"]
    for row in rows:
        median = row["cpu_ms_per_frame"]["median"]
        row["speedup_vs_plain"] = base / median if base and median else None
    return {
        "dataset": str(root),
        "frame_size": list(frame_size),
        "opencv_threads": cv2.getNumThreads(),
        "timing": "pipeline only, decode excluded; cpu = calling thread's CPU time, wall beside it; the predicted "
        "light timed apart (light_cpu_ms_per_frame) and counted in pi_fps_at_10x",
        "baseline": rows[0]["variant"],
        "variants": rows,
    }


def _f(value: Any, fmt: str) -> str:
    return "n/a" if value is None else format(value, fmt)


def format_table(report: dict[str, Any]) -> str:
    head = (
        f"{'variant':<26} {'work size':>9} {'cpu ms med':>10} {'cpu ms p95':>10} {'wall med':>8} "
        f"{'light med':>9} {'speedup':>7} {'F1':>6} {'loc px med':>10} {'AUC':>6} {'Pi fps':>6}"
    )
    lines = [f"dataset: {report['dataset']} (OpenCV threads: {report['opencv_threads']})", head, "-" * len(head)]
    for row in report["variants"]:
        cpu, wall = row["cpu_ms_per_frame"], row["wall_ms_per_frame"]
        lines.append(
            f"{row['variant']:<26} {row['width']:>4}x{row['height']:<4} {_f(cpu['median'], '10.3f')} "
            f"{_f(cpu['p95'], '10.3f')} {_f(wall['median'], '8.3f')} {_f(row['light_cpu_ms_per_frame']['median'], '9.3f')} "
            f"{_f(row['speedup_vs_plain'], '6.1f')}x "
            f"{_f(row['f1'], '6.3f')} {_f(row['localisation_error_px_median'], '10.2f')} {_f(row['anchoring_auc'], '6.3f')} "
            f"{_f(row.get('pi_fps_at_10x'), '6.1f')}"
        )
    for name, sub in report.get("conditions", {}).items():
        lines += ["", f"condition {name}:", *format_table(sub).splitlines()[1:]]
    return "\n".join(lines)


def run_bench(args: argparse.Namespace) -> int:
    config = load_config(args.config).touch
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        if args.dataset:
            return _bench_on(Path(args.dataset), config, args)
        from feelium.lab.sim.protocol import simulate_protocol

        with tempfile.TemporaryDirectory(prefix="feelium-bench-touch-") as tmp:
            print(f"simulating the paper protocol (seed {args.seed}, scale {args.scale}) into {tmp} ...", file=sys.stderr)
            simulate_protocol(tmp, seed=args.seed, scale=args.scale, jobs=1, thermal=False)
            return _bench_on(Path(tmp), config, args)
    finally:
        cv2.setNumThreads(threads)


def _bench_on(root: Path, config: TouchConfig, args: argparse.Namespace) -> int:
    paths = find_recordings(root)
    if not paths:
        print(f"feelium bench touch: {root} holds no recording", file=sys.stderr)
        return 1
    by_condition = getattr(args, "by_condition", False)
    variants = build_variants(config)
    sizes = run_variants(root, variants, progress=getattr(args, "progress", False), by_condition=by_condition)
    if not sizes:
        print(f"feelium bench touch: {root} holds no labelled recording", file=sys.stderr)
        return 1
    report = summarise(root, variants, next(iter(sizes.values())))
    if by_condition:
        report["conditions"] = {
            name: summarise(root, [v.by_condition[name] for v in variants], sizes[name]) for name in sorted(sizes)
        }
    print(format_table(report))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
        print(f"report: {args.json}")
    return 0
