"""Run the pipeline over a recording exactly as the daemon would on its frames.

Shared by `feelium replay`, `feelium eval`, `feelium calibrate touch` and
`feelium bench touch`, so they all score the same thing. Decoding is timed
apart from the pipeline: speed figures are the pipeline alone.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from feelium.events import TouchEvent
from feelium.recording import Recording, RecordingError
from feelium.skin.face import FaceModel
from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import FrameResult, TouchPipeline
from feelium.touch.sensing import PROBLEMS, SensingMonitor, sample_of, share_taught


@dataclass
class ReplayResult:
    """Everything one recording produced: events, per-frame series and timings."""

    recording: Recording
    events: list[TouchEvent] = field(default_factory=list)
    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    activity: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    anchor: np.ndarray = field(default_factory=lambda: np.zeros(0))
    area: np.ndarray = field(default_factory=lambda: np.zeros(0))
    depth_max: np.ndarray = field(default_factory=lambda: np.zeros(0))
    core_depth: np.ndarray = field(default_factory=lambda: np.zeros(0))
    edge: np.ndarray = field(default_factory=lambda: np.zeros(0))  # the deepest shadow's contact edge
    # the largest share of the projector's own light a shadow took (NaN: its share unknown, or no shadow)
    projected_depth: np.ndarray = field(default_factory=lambda: np.zeros(0))
    seconds_per_frame: np.ndarray = field(default_factory=lambda: np.zeros(0))  # wall time
    cpu_seconds_per_frame: np.ndarray = field(default_factory=lambda: np.zeros(0))  # this thread's CPU time
    # The CPU time of each frame's predicted light (0 without a projector stream), timed apart from the pipeline's.
    light_cpu_seconds_per_frame: np.ndarray = field(default_factory=lambda: np.zeros(0))
    work_size: tuple[int, int] = (0, 0)
    # Per frame, the touch service's verdict on its own light (:mod:`feelium.touch.sensing`): each condition
    # present on the frame, and each that had lasted long enough for health to say ``degraded`` (keys of PROBLEMS).
    light_present: dict[str, np.ndarray] = field(default_factory=dict)
    light_degraded: dict[str, np.ndarray] = field(default_factory=dict)


def face_of(recording: Recording) -> FaceModel | None:
    """The recording's optional whole-face model (``meta["face"]``, docs/recording-format.md), None without one.

    A recording without it is the paper's rectangle (its ``roi``), exactly as before.
    """
    raw = recording.meta.raw.get("face")
    if raw is None:
        return None
    where = recording.path / "meta.json"
    try:
        face = FaceModel.from_json(raw)
    except ValueError as exc:
        raise RecordingError(where, str(exc)) from exc
    camera = recording.meta.camera
    if (face.width, face.height) != (camera.width, camera.height):
        raise RecordingError(
            where, f"face: the model is for {face.width}x{face.height} frames, the camera's are {camera.width}x{camera.height}"
        )
    return face


def new_pipeline(
    recording: Recording,
    config: TouchConfig,
    light: Callable[[float], dict[str, np.ndarray]] | None = None,
    *,
    plain: bool = False,
) -> TouchPipeline:
    """A fresh pipeline for ``recording``'s frames (its size, ROI and face), as the daemon builds one, with ``light``
    (a recording's predicted light) told where the pipeline reads it."""
    meta = recording.meta
    size = (meta.camera.width, meta.camera.height)
    pipeline = TouchPipeline(config, size, meta.roi, plain=plain, face=face_of(recording))
    use_grids = getattr(light, "use_grids", None)
    if use_grids is not None:  # a recording's light, predicted where the pipeline reads it (the daemon's way)
        use_grids(pipeline.light_grids)
    return pipeline


def replay_recording(
    recording: Recording,
    config: TouchConfig,
    *,
    plain: bool = False,
    on_frame: Callable[[float, np.ndarray, FrameResult], None] | None = None,
    frames: Iterator[tuple[float, np.ndarray]] | None = None,
    light: Callable[[float], dict[str, np.ndarray]] | None = None,
) -> ReplayResult:
    """Feed every frame of ``recording`` through a fresh pipeline; ``on_frame`` sees each result.

    ``light``: per frame time, the projected light the daemon would pass with the frame
    (:class:`feelium.lab.touch.recorded_light.RecordedLight` for a recording with a projector stream).
    """
    pipeline = new_pipeline(recording, config, light, plain=plain)
    out = ReplayResult(recording=recording)
    monitor = SensingMonitor()  # fed as the touch service feeds it: the same judge, its own hold
    taught = share_taught(config.contact_projected_depth, light is not None)
    present: dict[str, list[bool]] = {p: [] for p in PROBLEMS}
    degraded: dict[str, list[bool]] = {p: [] for p in PROBLEMS}
    ts, act, anc, area, dmax, core, edge, proj, spf, cpu, light_cpu = [], [], [], [], [], [], [], [], [], [], []
    for t, frame in frames if frames is not None else recording.frames(gray=True):
        extra: dict[str, Any] = {}
        if light is None:
            light_cpu.append(0.0)
        else:  # timed apart: the pipeline's figure stays the pipeline's
            start_cpu = time.thread_time()
            extra = light(t)
            light_cpu.append(time.thread_time() - start_cpu)
        start, start_cpu = time.perf_counter(), time.thread_time()
        result = pipeline.process(t, frame, **extra)
        cpu.append(time.thread_time() - start_cpu)
        spf.append(time.perf_counter() - start)
        out.events.extend(result.events)
        ts.append(t)
        act.append(result.activity)
        anc.append(result.anchor)
        area.append(result.area)
        dmax.append(result.depth_max)
        core.append(result.core_depth)
        edge.append(result.edge)
        proj.append(math.nan if result.projected_depth is None else result.projected_depth)
        sample = sample_of(pipeline, t, taught)
        if sample is not None:
            monitor.update(sample)
        now, lasting = monitor.present(), monitor.lasting()
        for problem in PROBLEMS:
            present[problem].append(problem in now)
            degraded[problem].append(problem in lasting)
        if on_frame is not None:
            on_frame(t, frame, result)
    out.events.extend(pipeline.finish())
    out.t = np.asarray(ts, float)
    out.activity = np.asarray(act, bool)
    out.anchor = np.asarray(anc, float)
    out.area = np.asarray(area, float)
    out.depth_max = np.asarray(dmax, float)
    out.core_depth = np.asarray(core, float)
    out.edge = np.asarray(edge, float)
    out.projected_depth = np.asarray(proj, float)
    out.seconds_per_frame = np.asarray(spf, float)
    out.cpu_seconds_per_frame = np.asarray(cpu, float)
    out.light_cpu_seconds_per_frame = np.asarray(light_cpu, float)
    out.work_size = pipeline.geometry.work_size
    out.light_present = {p: np.asarray(v, bool) for p, v in present.items()}
    out.light_degraded = {p: np.asarray(v, bool) for p, v in degraded.items()}
    return out


def relative_name(root: Path, recording_path: Path) -> str:
    """A recording's path relative to the dataset root, as the spec's ``"recording"`` key wants it."""
    try:
        rel = recording_path.resolve().relative_to(root.resolve())
    except ValueError:
        return recording_path.name
    return rel.as_posix() if str(rel) != "." else "."
