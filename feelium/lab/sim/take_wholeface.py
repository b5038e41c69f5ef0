"""Whole-face trials with the wearer's face on the skin, in a lit room, or both: issue 17's conditions at once.

The ``face`` condition's trials (:mod:`feelium.lab.touch.face_zones`: taps, holds, swipes and hovers aimed at a
zone of the whole curved front face, 1280x960 frames) under the light of the two rectangle-only conditions,
built from the same worlds and none of it chosen from detector scores:

- ``faceon``: the face-on take's world (:mod:`feelium.lab.sim.take_faceon`: the scripted wearer's video at full
  brightness, shown through the daemon's renderer, lit :data:`~feelium.lab.touch.faceon.TRUE_LATENCY_S` after its
  frame clock and integrated over the exposure, its 5 s hand-free warm-up recorded before 0 s), seen on the face's
  frame: the simulator's projector optics at the face's resolution
  (:meth:`feelium.sim.projection.FisheyeWarp.scaled`, the projector's image covers the face), the Gray-code
  calibration decoded on that frame over the face's box (so the map the recording carries covers the whole face,
  rim included, and not only the paper's rectangle), and the renderer drawing the canvas over the face's u, v as
  the daemon does with ``[touch] face_model = "sphere"``;
- ``lit``: the lit room of :mod:`feelium.lab.touch.litroom` (``room_for("lit")``: room light through the
  membrane as bright as the projector's, a lamp gradient at the trial's own angle, the camera's auto-exposure),
  on the static skin with the probe laid on it as in ``litroom`` (:func:`feelium.lab.sim.take_litroom.probe_frames`,
  through the face's map), with its 3 s warm-up in that light;
- ``faceon-lit``: the face on in that lit room (``faceon``'s ``face-lit``: no probe over a playing face).

Each take carries its projector stream; the face's map is written beside the trials
(:func:`feelium.lab.sim.conditions.simulate_condition`). The hands, target and session are the ``face``
condition's (same RNG streams by trial name); the warm-up takes the camera's first noise, so the frames are
not the plain variant's to the bit.
"""

from __future__ import annotations

from feelium.lab.sim import protocol, scripts, take_faceon, take_litroom
from feelium.lab.touch import face_zones, faceon, litroom
from feelium.sim.projection import timed_hook
from feelium.sim.scene import SceneRenderer
from feelium.sim.sessions import session_presets
from feelium.skin.face import FaceModel

LIGHTS = ("faceon", "lit", "faceon-lit")


def variant_light(variant: str) -> tuple[str, str | None]:
    """``"edge-faceon-lit"`` -> ``("edge", "faceon-lit")``; a bare zone -> ``(zone, None)`` (the flat back-light)."""
    zone, _, light = variant.partition("-")
    return zone, light or None


def variants() -> tuple[str, ...]:
    """Every zone under the flat back-light, then every zone under each light of :data:`LIGHTS`."""
    return face_zones.ZONES + tuple(f"{zone}-{light}" for light in LIGHTS for zone in face_zones.ZONES)


def render(
    trial: face_zones.Trial, light: str, seed: int, script: scripts.Script, face: FaceModel
) -> take_faceon.ProjectedTake:
    """``trial`` (its ``script`` aimed on ``face``) under ``light`` (one of :data:`LIGHTS`), with its projector stream."""
    if light not in LIGHTS:
        raise ValueError(f"face: unknown light {light!r}; expected one of {', '.join(LIGHTS)}")
    ex = take_faceon.experiment(seed, (face.width, face.height))
    assert ex.setup.face == face, "the world's face is the one that fills the trial's frame"
    fps = ex.setup.script.fps
    session = session_presets(seed)[trial.session]
    labels = script.labels()
    first = labels.contacts[0].t_on if labels.contacts else None
    room = litroom.room_for("lit", trial, seed, script.duration, first) if light.endswith("lit") else None
    if light.startswith("faceon"):
        offset = float(protocol.recording_rng(seed, trial.name, 7).uniform(0.0, ex.setup.script.fade_every_s))
        shown = faceon._Cache(faceon.FaceVideo(ex.renderer, ex.source, ex.setup.script, offset).frame)
        warmup = faceon.WARMUP_S
    else:
        offset, shown, warmup = 0.0, take_litroom.probe_frames(ex), litroom.WARMUP_S
    hook = timed_hook(ex.light, shown, fps, faceon.TRUE_LATENCY_S, session.sensor.exposure_s)
    rng = protocol.recording_rng(seed, trial.name, 1)
    scene = SceneRenderer(
        session, rng, roi=face.roi(), face=face, projected=hook, projected_share_only=True, room_light=room
    )  # fmt: skip
    config = ex.setup.projector
    return take_faceon.ProjectedTake(
        take_faceon.warmed_frames(scene, script, session, rng, warmup),
        labels,
        take_faceon.stream(shown, fps, warmup, script.duration),
        (config.width, config.height),
        fps,
        offset,
        room,
    )
