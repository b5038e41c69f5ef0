"""Labelled recordings of issue 17's conditions of use, for ``feelium simulate condition`` and ``feelium eval``.

Each condition is written as one dataset folder per variant, ``OUT/<condition>-<variant>/...``, in recording
format v1 and nothing else: the frames, the labels of the trial's script and, in ``meta.json``, the
``"generator"`` key the spec allows (seed, scale, the condition as ``"condition": "<condition>/<variant>"`` and
its parameters) plus, for the whole face, the optional ``"face"`` model. ``feelium eval OUT --by-condition``
scores every variant on its own. The worlds are the lab experiments' (their parameters stated there, none
chosen from detector scores):

- ``litroom``: the protocol's trials under each room light of :mod:`feelium.lab.touch.litroom` (``dim``,
  ``lit``, ``switch-on``, ``switch-off``, ``drift``, ``passer-by``), with its hand-free warm-up in the
  starting light recorded as frames before 0 s, the static skin with the probe as the projector stream and the
  projector calibration beside the trials (:mod:`feelium.lab.sim.take_litroom`);
- ``face``: taps, holds, swipes and hovers aimed at targets in each zone of the whole curved front face
  (:mod:`feelium.lab.touch.face_zones`: ``centre``, ``mid``, ``edge``), 1280x960 frames with ``meta.face``; per
  zone also under the wearer's face projected, the lit room, or both (``edge-faceon``, ``edge-lit``,
  ``edge-faceon-lit``: :mod:`feelium.lab.sim.take_wholeface`), with the projector stream and the face's own
  projector calibration beside the trials;
- ``faceon``: the protocol's trials under the flat back-light (``static``) and with the wearer's face on the
  skin (``face``), each also in the lit room (``static-lit``, ``face-lit``), the face with the projector stream
  recorded and the projector calibration written beside the trials (:mod:`feelium.lab.sim.take_faceon`);
- ``multitouch``: the scene bench's two fingers, two hands 5 cm apart, two partners, swipes crossing a held
  fingertip, palm, palm and finger, hug (:mod:`feelium.lab.sim.take_multitouch`), each true contact labelled
  with the optional ``"contact"`` kind, scored contact by contact by ``eval``.

Every recording draws from its own RNG streams keyed by (seed, its name), exactly as the experiments do, so a
recording here replays to the experiment's own events.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2

from feelium.lab.sim import protocol, take_faceon, take_litroom, take_multitouch, take_wholeface
from feelium.lab.touch import face_zones, litroom
from feelium.lab.touch.recorded_light import CALIBRATION_FILE
from feelium.recording import Labels, RecordingWriter
from feelium.sim.scene import HEIGHT, ROI, WIDTH, SceneRenderer, exposure_samples
from feelium.sim.camera import frame_times
from feelium.sim.sessions import session_presets
from feelium.skin import probe
from feelium.skin.face import FaceModel

CONDITIONS: dict[str, tuple[str, ...]] = {
    "litroom": litroom.CONDITIONS,
    "face": take_wholeface.variants(),
    "faceon": take_faceon.VARIANTS,
    "multitouch": take_multitouch.VARIANTS,
}
# What ``simulate condition`` writes without ``--variants``: every variant, except the whole face's lights (each
# several times the flat face's cost: ask for them, ``--variants edge-faceon,edge-lit``).
DEFAULT_VARIANTS: dict[str, tuple[str, ...]] = {**CONDITIONS, "face": face_zones.ZONES}
GENERATOR = "feelium.sim.conditions"
GENERATOR_VERSION = 1


@dataclass(frozen=True)
class Job:
    """One recording to write: which condition, variant and trial (a protocol item or a face trial)."""

    condition: str
    variant: str
    relpath: str
    trial: protocol.Item | face_zones.Trial | take_multitouch.Run
    frame: tuple[int, int] = face_zones.FRAME  # the whole face's camera frame (its lens fills it)


def plan(condition: str, variants: tuple[str, ...], scale: float, clips: bool = False) -> list[Job]:
    """The recordings of ``condition``'s ``variants`` at ``scale`` (the protocol's trials, or face trials per zone).

    ``clips``: litroom and faceon also get the protocol's continuous contact, hover and empty clips, so the
    gates can be fitted under the condition (``feelium calibrate touch``, ``eval --fit-on-clips``)."""
    known = CONDITIONS.get(condition)
    if known is None:
        raise ValueError(f"unknown condition {condition!r}; expected one of {', '.join(CONDITIONS)}")
    bad = [v for v in variants if v not in known]
    if bad:
        raise ValueError(f"{condition}: unknown variant(s) {', '.join(bad)}; expected some of {', '.join(known)}")
    jobs: list[Job] = []
    if condition in ("litroom", "faceon"):
        trials = [item for item in protocol.plan(scale) if clips or not item.clip]
        for variant in variants:
            jobs += [Job(condition, variant, f"{condition}-{variant}/{item.relpath}", item) for item in trials]
    elif condition == "multitouch":
        for variant in variants:
            jobs += [
                Job(condition, variant, f"{condition}-{variant}/{run.session}/{run.name}", run)
                for run in take_multitouch.runs(variant, scale)
            ]
    else:
        per_cell = max(1, int(round(5 * scale)))  # the face bench's 5 trials per label and zone at scale 1
        trials = face_zones.plan(per_cell)
        for variant in variants:
            zone, _ = take_wholeface.variant_light(variant)
            jobs += [
                Job(condition, variant, f"{condition}-{variant}/{trial.session}/{trial.name}", trial)
                for trial in trials if trial.zone == zone
            ]  # fmt: skip
    return jobs


def write_job(job: Job, out: Path, seed: int, scale: float, *, overwrite: bool = False) -> Path:
    """Render and write one recording of ``job``."""
    generator: dict[str, Any] = {
        "name": GENERATOR, "version": GENERATOR_VERSION, "seed": seed, "scale": scale,
        "condition": f"{job.condition}/{job.variant}",
    }  # fmt: skip
    take: take_faceon.ProjectedTake | None = None
    if job.condition == "litroom":
        (frames, labels, size, roi, extra), take = _litroom(job, seed, generator)
    elif job.condition == "faceon":
        (frames, labels, size, roi, extra), take = _faceon(job, seed, generator)
    elif job.condition == "multitouch":
        frames, labels, size, roi, extra = _multitouch(job, seed, generator)
    else:
        (frames, labels, size, roi, extra), take = _face(job, seed, generator)
    session = job.trial.session
    fps = session_presets(seed)[session].sensor.fps
    with RecordingWriter(
        out / job.relpath, name=Path(job.relpath).name, width=size[0], height=size[1], fps=fps, session=session,
        source="synthetic", roi=roi, extra_meta={"generator": protocol._jsonable(generator), **extra}, overwrite=overwrite,
    ) as writer:  # fmt: skip
        if take is not None and take.projector is not None:
            writer.set_projector(*take.projector_size, take.projector_fps)
            _write_interleaved(writer, frames, take.projector)
        else:
            for t, frame in frames:
                writer.add_frame(t, frame)
        writer.set_labels(labels)
    return out / job.relpath


Rendered = tuple[Iterator[tuple[float, Any]], Any, tuple[int, int], tuple[int, int, int, int], dict[str, Any]]


def _litroom(job: Job, seed: int, generator: dict[str, Any]) -> tuple[Rendered, take_faceon.ProjectedTake]:
    item = job.trial
    assert isinstance(item, protocol.Item)
    take = take_litroom.render(item, job.variant, seed)
    generator.update(room=None if take.room is None else dataclasses.asdict(take.room), warmup_s=litroom.WARMUP_S,
                     probe={"amplitude": probe.AMPLITUDE, "period_s": probe.PERIOD_S},
                     projector_latency_s=take_faceon.faceon.TRUE_LATENCY_S)  # fmt: skip
    return (take.frames, take.labels, (WIDTH, HEIGHT), ROI, {}), take


def _face(job: Job, seed: int, generator: dict[str, Any]) -> tuple[Rendered, take_faceon.ProjectedTake | None]:
    trial = job.trial
    assert isinstance(trial, face_zones.Trial)
    face = FaceModel.for_frame(*job.frame)
    script, (u, v) = face_zones.build_script(face, trial, seed)
    generator["target_uv"] = [u, v]
    roi = face.roi()
    labels = aimed_labels(script.labels(), face, (u, v))
    extra = {"face": face.to_json()}
    _, light = take_wholeface.variant_light(job.variant)
    if light is not None:  # the face projected and/or the room lit: the take carries its projector stream
        take = take_wholeface.render(trial, light, seed, script, face)
        generator.update(
            light=light, warmup_s=take_faceon.faceon.WARMUP_S if light.startswith("faceon") else litroom.WARMUP_S,
            projector_latency_s=take_faceon.faceon.TRUE_LATENCY_S, room=None if take.room is None else dataclasses.asdict(take.room),
        )  # fmt: skip
        if light.startswith("faceon"):
            generator["video_offset_s"] = take.offset_s
        else:
            generator["probe"] = {"amplitude": probe.AMPLITUDE, "period_s": probe.PERIOD_S}
        return (take.frames, labels, job.frame, roi, extra), take
    session = session_presets(seed)[trial.session]
    rng = protocol.recording_rng(seed, trial.name, 1)
    scene = SceneRenderer(session, rng, roi=roi, face=face)

    def frames() -> Iterator[tuple[float, Any]]:
        for t in frame_times(session.sensor, script.duration, rng):
            yield float(t), scene.frame(float(t), exposure_samples(script.state, float(t), session.sensor.exposure_s))

    return (frames(), labels, job.frame, roi, extra), None


def aimed_labels(labels: Labels, face: FaceModel, uv: tuple[float, float]) -> Labels:
    """``labels`` with a hover's prompted point as its ``target`` (camera px), the others as they are.

    Why: the protocol's hovers carry no target (a hover has no landing), but on the whole face each is aimed at a
    point drawn in its zone, and ``eval``'s zones place a trial without a contact by its target: without it every
    hover was ``unplaced``, and no zone could say whether its hovers fire (the rim, where the back-light is
    dimmest, above all)."""
    if labels.label != "hover" or labels.target is not None:
        return labels
    x, y = face.to_camera(*uv)
    return dataclasses.replace(labels, target=(float(x), float(y)))


def _faceon(job: Job, seed: int, generator: dict[str, Any]) -> tuple[Rendered, take_faceon.ProjectedTake]:
    item = job.trial
    assert isinstance(item, protocol.Item)
    take = take_faceon.render(item, job.variant, seed)
    generator.update(warmup_s=take_faceon.faceon.WARMUP_S, video_offset_s=take.offset_s,
                     projector_latency_s=take_faceon.faceon.TRUE_LATENCY_S,
                     room=None if take.room is None else dataclasses.asdict(take.room))  # fmt: skip
    return (take.frames, take.labels, (WIDTH, HEIGHT), ROI, {}), take


def _write_interleaved(
    writer: RecordingWriter, frames: Iterator[tuple[float, Any]], shown: Iterator[tuple[float, Any]]
) -> None:
    """Each camera frame after the projector frames shown up to its time: the projector stream then runs just
    ahead of the camera's light, from the same small cache, so each projector frame is rendered once."""
    pending = next(shown, None)
    for t, frame in frames:
        while pending is not None and pending[0] <= t:
            writer.add_projector_frame(*pending)
            pending = next(shown, None)
        writer.add_frame(t, frame)
    while pending is not None:
        writer.add_projector_frame(*pending)
        pending = next(shown, None)


def _multitouch(job: Job, seed: int, generator: dict[str, Any]) -> Rendered:
    run = job.trial
    assert isinstance(run, take_multitouch.Run)
    frames, labels = take_multitouch.render(run, seed)
    generator.update(scene=run.scene, rep=run.rep, warmup_s=take_multitouch.multitouch.WARMUP_S)
    return frames, labels, (WIDTH, HEIGHT), ROI, {}


def _write_star(args: tuple[Job, Path, int, float, bool]) -> str:
    job, out, seed, scale, overwrite = args
    return str(write_job(job, out, seed, scale, overwrite=overwrite))


def _single_threaded() -> None:
    cv2.setNumThreads(1)


def simulate_condition(
    out: str | Path,
    condition: str,
    *,
    variants: tuple[str, ...] | None = None,
    seed: int = 1,
    scale: float = 1.0,
    jobs: int = 1,
    overwrite: bool = False,
    progress: Callable[[int, int, str], None] | None = None,
    clips: bool = False,
) -> list[Path]:
    """Write every recording of ``condition`` (all its variants unless ``variants``) under ``out``."""
    if not (0.0 < scale <= 1.0):
        raise ValueError(f"scale must be in (0, 1], got {scale}")
    if clips and condition not in ("litroom", "faceon"):
        raise ValueError(f"{condition}: only litroom and faceon have continuous clips")
    todo = plan(condition, variants if variants else DEFAULT_VARIANTS.get(condition, ()), scale, clips)
    args = [(job, Path(out), seed, scale, overwrite) for job in todo]
    written: list[Path] = []
    if jobs <= 1:
        results: Iterator[str] = map(_write_star, args)
    else:  # spawned, as the protocol's: a fork of a threaded process can inherit a held lock
        pool = ProcessPoolExecutor(max_workers=jobs, initializer=_single_threaded, mp_context=multiprocessing.get_context("spawn"))
        results = pool.map(_write_star, args)
    try:
        for i, path in enumerate(results, start=1):
            written.append(Path(path))
            if progress:
                progress(i, len(todo), path)
    finally:
        if jobs > 1:
            pool.shutdown()
    # The map the daemon would use, beside the trials that carry a projector stream (`eval` finds it there): the
    # whole face's own, decoded on its frame, for the face's variants.
    for variant, frame in sorted({(job.variant, job.frame) for job in todo if carries_projector(condition, job.variant)}):
        face_frame = frame if condition == "face" else None
        take_faceon.calibration(seed, face_frame).save(Path(out) / f"{condition}-{variant}" / CALIBRATION_FILE)
    return sorted(written)


def carries_projector(condition: str, variant: str) -> bool:
    """Whether ``condition``'s ``variant`` records a projector stream (the map must then lie beside its trials)."""
    if condition == "litroom":
        return True
    if condition == "faceon":
        return variant.startswith("face")
    if condition == "face":
        return take_wholeface.variant_light(variant)[1] is not None
    return False
