"""The paper's evaluation protocol as a synthetic, labelled dataset.

228 trials over three sessions (78 taps, 24 holds, 36 swipes, 30 hovers, 30
disturbances, 30 empty scenes) plus three continuous clips (steady contact,
hovering, empty) of about 75 s, written in recording format v1. Every
recording draws from its own RNG seeded by (dataset seed, recording name), so
a recording does not change when others are added or the scale changes, and
recordings can be rendered in parallel processes with identical results.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Iterator
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from feelium.recording import RecordingWriter
from feelium.lab.sim import scripts
from feelium.sim.camera import frame_times
from feelium.sim.scene import HEIGHT, ROI, WIDTH, Projected, SceneRenderer, Session, exposure_samples
from feelium.sim.sessions import SESSION_NAMES, session_presets
from feelium.sim.warmth import THERMAL_FPS, render_thermal

GENERATOR = "feelium.sim"
GENERATOR_VERSION = 1
TRIAL_COUNTS = {"tap": 78, "hold": 24, "swipe": 36, "hover": 30, "disturbance": 30, "empty": 30}
CLIP_LABELS = ("contact", "hover", "empty")
CLIP_SECONDS = 75.0
MIN_CLIP_SECONDS = 6.0


@dataclass(frozen=True)
class Item:
    """One recording to produce: where, which session, what."""

    relpath: str  # directory under the dataset root
    name: str
    session: str
    label: str
    index: int  # index within its label (for the prompted target and the disturbance kind)
    clip: bool = False
    clip_seconds: float = CLIP_SECONDS


def class_counts(scale: float) -> dict[str, int]:
    """Trials per label at ``scale``: proportional, at least one of each."""
    if not (0.0 < scale <= 1.0):
        raise ValueError(f"scale must be in (0, 1], got {scale}")
    return {label: max(1, int(round(n * scale))) for label, n in TRIAL_COUNTS.items()}


def plan(scale: float = 1.0) -> list[Item]:
    """Every recording of the protocol at ``scale``: trials round-robin over sessions, then the clips."""
    items = []
    for label, count in class_counts(scale).items():
        for i in range(count):
            session = SESSION_NAMES[i % len(SESSION_NAMES)]
            name = f"{session}-{label}-{i // len(SESSION_NAMES) + 1:03d}"
            items.append(Item(f"{session}/{name}", name, session, label, i))
    clip_seconds = max(MIN_CLIP_SECONDS, CLIP_SECONDS * scale)
    for label in CLIP_LABELS:
        name = f"clip-{label}"
        items.append(Item(f"clips/{name}", name, "s1", label, 0, clip=True, clip_seconds=clip_seconds))
    return items


def recording_rng(seed: int, name: str, stream: int) -> np.random.Generator:
    """Independent RNG streams per recording: 0 = script, 1 = camera noise and timing, 2 = thermal."""
    return np.random.default_rng([seed, zlib.crc32(name.encode()), stream])


def aim_error(seed: int, session: str, target_index: int, rng: np.random.Generator) -> tuple[float, float]:
    """Where a partner lands relative to a prompt: a per-target habit plus per-trial scatter (px)."""
    habit_rng = np.random.default_rng([seed, zlib.crc32(session.encode()), target_index, 0xA1])
    bias = habit_rng.normal(0.0, 4.0, 2)
    scatter = float(habit_rng.uniform(3.0, 12.0))
    return float(bias[0] + rng.normal(0, scatter)), float(bias[1] + rng.normal(0, scatter))


def build_script(item: Item, seed: int, roi: tuple[int, int, int, int] = ROI) -> scripts.Script:
    """The script of one planned recording."""
    rng = recording_rng(seed, item.name, 0)
    if item.clip:
        if item.label == "contact":
            return scripts.contact_clip(rng, item.clip_seconds, roi)
        if item.label == "hover":
            return scripts.hover_clip(rng, item.clip_seconds, roi)
        return scripts.empty_clip(rng, item.clip_seconds)
    if item.label in scripts.PROMPTED:
        targets = scripts.prompted_targets(roi)
        target_index = (item.index * 4 + item.index // len(targets)) % len(targets)
        target = targets[target_index]
        aim = aim_error(seed, item.session, target_index, rng)
        return scripts.PROMPTED[item.label](rng, target, aim, roi)
    if item.label == "disturbance":
        return scripts.disturbance(rng, scripts.DISTURBANCE_KINDS[item.index % 3], roi)
    if item.label == "empty":
        return scripts.empty(rng, lighting_step=item.index % 2 == 1)
    raise ValueError(f"unknown label {item.label!r}")


def render_frames(
    script: scripts.Script, session: Session, rng: np.random.Generator, *, projected: Projected | None = None
) -> Iterator[tuple[float, np.ndarray]]:
    """``(t, frame)`` for every captured frame of ``script`` under ``session``."""
    renderer = SceneRenderer(session, rng, width=WIDTH, height=HEIGHT, roi=ROI, projected=projected)
    for t in frame_times(session.sensor, script.duration, rng):
        states = exposure_samples(script.state, float(t), session.sensor.exposure_s)
        yield float(t), renderer.frame(float(t), states)


def write_item(
    item: Item,
    out: Path,
    seed: int,
    scale: float,
    *,
    projected_factory: Callable[[Item], Projected | None] | None = None,
    overwrite: bool = False,
    thermal: bool = True,
) -> Path:
    """Render and write one recording (with ``thermal.npz`` at 8 Hz unless ``thermal`` is False)."""
    session = session_presets(seed)[item.session]
    script = build_script(item, seed)
    rng = recording_rng(seed, item.name, 1)
    projected = projected_factory(item) if projected_factory is not None else None
    generator: dict[str, Any] = {
        "name": GENERATOR,
        "version": GENERATOR_VERSION,
        "seed": seed,
        "scale": scale,
        "item": {"label": item.label, "index": item.index, "clip": item.clip},
        "session": session.to_json(),
        "script": _jsonable(script.params),
    }
    with RecordingWriter(
        out / item.relpath,
        name=item.name,
        width=WIDTH,
        height=HEIGHT,
        fps=session.sensor.fps,
        session=item.session,
        source="synthetic",
        roi=ROI,
        extra_meta={"generator": generator},
        overwrite=overwrite,
    ) as writer:
        for t, frame in render_frames(script, session, rng, projected=projected):
            writer.add_frame(t, frame)
        writer.set_labels(script.labels())
        if thermal:
            data = render_thermal(
                script.state, script.duration, ROI, session.shadow.px_per_mm, session.ambient_c,
                recording_rng(seed, item.name, 2),
            )  # fmt: skip
            writer.set_thermal(data, THERMAL_FPS)
    return out / item.relpath


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, float):
        return round(value, 4) if math.isfinite(value) else None
    if isinstance(value, (np.floating, np.integer)):
        return _jsonable(value.item())
    return value


def _write_star(args: tuple[Item, Path, int, float, bool, bool]) -> str:
    item, out, seed, scale, overwrite, thermal = args
    return str(write_item(item, out, seed, scale, overwrite=overwrite, thermal=thermal))


def _single_threaded() -> None:
    """Worker processes already use every core; OpenCV's own threads would only contend."""
    cv2.setNumThreads(1)


def simulate_protocol(
    out: str | Path,
    *,
    seed: int = 1,
    scale: float = 1.0,
    jobs: int = 1,
    overwrite: bool = False,
    thermal: bool = True,
    progress: Callable[[int, int, str], None] | None = None,
) -> list[Path]:
    """Write the whole protocol under ``out``; ``jobs`` > 1 renders recordings in parallel processes."""
    out = Path(out)
    items = plan(scale)
    # Longest first, so parallel workers finish together.
    order = sorted(items, key=lambda it: -it.clip_seconds if it.clip else 0.0)
    args = [(item, out, seed, scale, overwrite, thermal) for item in order]
    written: list[Path] = []
    if jobs <= 1:
        results: Iterator[str] = map(_write_star, args)
        for i, path in enumerate(results, start=1):
            written.append(Path(path))
            if progress:
                progress(i, len(items), path)
    else:
        # Spawned, not forked: a fork of a process that already runs threads (OpenCV's pool, asyncio's
        # executors, a test runner's fixtures) can inherit a held lock and hang the worker forever.
        spawn = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, initializer=_single_threaded, mp_context=spawn) as pool:
            for i, path in enumerate(pool.map(_write_star, args), start=1):
                written.append(Path(path))
                if progress:
                    progress(i, len(items), path)
    return sorted(written)

