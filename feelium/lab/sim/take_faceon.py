"""One protocol trial with the wearer's face on the skin, as a recording that carries what was projected.

The world is the face-on experiment's (:mod:`feelium.lab.touch.faceon`, its parameters stated there and none
chosen from detector scores): the scripted wearer's video at full brightness (talking avatar, head sway,
scene cuts, fades to black and back) shown through the daemon's renderer with its sensing and fade floors,
lit on the membrane :data:`~feelium.lab.touch.faceon.TRUE_LATENCY_S` after its frame clock and integrated over
the camera's exposure; the same hands, session, camera noise and video offset per trial, and the same
hand-free warm-up (recorded here as frames before 0 s). Four variants:

- ``static``: the flat back-light, the baseline every face figure is read against;
- ``face``: the face on, with the projector stream recorded: every projector frame the daemon handed the
  display, gray, with the time it did so (its frame clock, ``k / fps``; the daemon knows when it showed a
  frame, not when the light reached the membrane, which is what ``[touch] projector_latency_s`` models);
- ``static-lit`` and ``face-lit``: the same two in the lit living room of the lit-room experiment
  (:func:`feelium.lab.touch.litroom.room_for` ``"lit"``: the room's light through the membrane as bright as the
  projector's, the trial's own gradient angle, steady), the room's light in the warm-up too. With the face on,
  its own variation is all that teaches the pipeline the projector's share of the light (no probe is laid over
  a playing face).

The camera-to-projector map the daemon would use is the Gray-code calibration run against the same simulated
optics (:func:`feelium.lab.projector.facevideo.sim_calibration`, a decode, not the true warp); the dataset
writes it beside the trials as ``projector-calibration.npz``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from feelium.lab.sim import protocol
from feelium.lab.touch import faceon, litroom
from feelium.projector.config import ProjectorConfig
from feelium.recording import Labels
from feelium.sim.camera import frame_times
from feelium.sim.projection import timed_hook
from feelium.sim.room import RoomLight
from feelium.sim.scene import ROI, SceneRenderer, SceneState, Session, exposure_samples
from feelium.sim.sessions import session_presets
from feelium.skin.face import FaceModel
from feelium.skin.projector_map import ProjectorMap
from feelium.touch.config import TouchConfig

VARIANTS = ("static", "face", "static-lit", "face-lit")


@dataclass
class ProjectedTake:
    """The camera frames (warm-up first), labels and the projector stream, when one was recorded (the face on
    here; the still skin with the probe in :mod:`feelium.lab.sim.take_litroom`)."""

    frames: Iterator[tuple[float, np.ndarray]]
    labels: Labels
    projector: Iterator[tuple[float, np.ndarray]] | None
    projector_size: tuple[int, int]
    projector_fps: float
    offset_s: float
    room: RoomLight | None  # the room's own light (None: the paper's dim room)


@functools.lru_cache(maxsize=2)
def experiment(seed: int, face_frame: tuple[int, int] | None = None) -> faceon._Experiment:
    """The experiment's world (the calibration decoded once per process and seed); ``face_frame``: the same world
    seen on the whole curved face filling a camera frame of that size (:meth:`FaceModel.for_frame`; the face
    condition's is :data:`feelium.lab.touch.face_zones.FRAME`), its calibration decoded over the face."""
    face = None if face_frame is None else FaceModel.for_frame(*face_frame)
    return faceon._Experiment(faceon._Setup(seed, ProjectorConfig(), TouchConfig(), faceon.FaceScript(), face=face))


def calibration(seed: int, face_frame: tuple[int, int] | None = None) -> ProjectorMap:
    """The camera-to-projector map decoded from the simulated Gray-code run (what a user's calibration gives)."""
    return experiment(seed, face_frame).calibration


def warmed_frames(
    scene: SceneRenderer, script: Any, session: Session, rng: np.random.Generator, warmup_s: float
) -> Iterator[tuple[float, np.ndarray]]:
    """The camera's frames: ``warmup_s`` hand-free before 0 s (the membrane as it was before the trial), then the
    trial's at the session's own times (jitter, drops), each integrated over the exposure."""
    for t in np.arange(-warmup_s, -0.25, 1.0 / session.sensor.fps):
        yield float(t), scene.frame(float(t), SceneState())
    for t in frame_times(session.sensor, script.duration, rng):
        yield float(t), scene.frame(float(t), exposure_samples(script.state, float(t), session.sensor.exposure_s))


def stream(shown: Callable[[int], np.ndarray], fps: float, warmup_s: float, duration: float) -> Iterator[tuple[float, np.ndarray]]:
    """The projector stream: frame ``k`` at its frame clock ``k / fps``, from before the warm-up to the trial's end.

    ``shown`` is the same cache as the camera's light: written interleaved with the camera frames (``write_job``),
    the stream runs a frame or two ahead of the light and each projector frame is rendered once."""
    for k in range(math.floor(-warmup_s * fps) - 2, math.ceil(duration * fps) + 1):
        yield k / fps, shown(k)


def render(item: protocol.Item, variant: str, seed: int) -> ProjectedTake:
    """``item`` under ``variant`` (one of :data:`VARIANTS`)."""
    if variant not in VARIANTS:
        raise ValueError(f"faceon: unknown variant {variant!r}")
    face_on = variant.startswith("face")
    ex = experiment(seed)
    fps = ex.setup.script.fps
    script = protocol.build_script(item, seed)
    session = session_presets(seed)[item.session]
    offset = float(protocol.recording_rng(seed, item.name, 7).uniform(0.0, ex.setup.script.fade_every_s))
    video = faceon.FaceVideo(ex.renderer, ex.source, ex.setup.script, offset)
    shown = faceon._Cache(video.frame)
    hook = timed_hook(ex.light, shown, fps, faceon.TRUE_LATENCY_S, session.sensor.exposure_s) if face_on else None
    labels = script.labels()
    first = labels.contacts[0].t_on if labels.contacts else None
    room = litroom.room_for("lit", item, seed, script.duration, first) if variant.endswith("-lit") else None
    rng = protocol.recording_rng(seed, item.name, 1)
    scene = SceneRenderer(session, rng, roi=ROI, projected=hook, projected_share_only=True, room_light=room)

    frames = warmed_frames(scene, script, session, rng, faceon.WARMUP_S)
    projector = stream(shown, fps, faceon.WARMUP_S, script.duration) if face_on else None
    config = ex.setup.projector
    return ProjectedTake(frames, labels, projector, (config.width, config.height), fps, offset, room)
