"""One lit-room trial as a recording that carries what was projected: the static skin with the probe laid on it.

The lit-room experiment (:mod:`feelium.lab.touch.litroom`) hands its pipeline the probe's ideal light, the
camera-pixel checkerboard times the level at the camera's time. A recording cannot carry that: what the daemon
knows is what it showed. So here the projector shows what the daemon shows on a static skin (the flat grey,
:attr:`ProjectorConfig.flat_level`) with the probe laid over it through the decoded camera-to-projector map
(:class:`feelium.projector.probe.ProbeOverlay`, 8-bit, as on the blimp), each frame at ``k / fps`` with the level
of that time; the membrane is lit by those frames through the simulator's true optics,
:data:`~feelium.lab.touch.faceon.TRUE_LATENCY_S` after their frame clock and mixed over the camera's exposure
(:func:`feelium.sim.projection.timed_hook`). The projector stream is written with the trial and the decoded map
beside the trials, so ``replay``/``eval`` predict the projected light from the recorded frames, as the daemon
does from its canvas, instead of scoring a probe it cannot see as if it were the room's light.

The room, hands, session, noise and warm-up are the experiment's (the same RNG streams: only the probe's
route differs), the projector world the face-on take's (:func:`feelium.lab.sim.take_faceon.experiment`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from feelium.lab.sim import protocol, take_faceon
from feelium.lab.touch import faceon, litroom
from feelium.projector.probe import ProbeOverlay
from feelium.sim.projection import timed_hook
from feelium.sim.sessions import session_presets
from feelium.skin.probe import probe_level


def render(item: protocol.Item, variant: str, seed: int) -> take_faceon.ProjectedTake:
    """``item`` in the room of ``variant`` (one of :data:`feelium.lab.touch.litroom.CONDITIONS`), with its
    projector stream."""
    if variant not in litroom.CONDITIONS:
        raise ValueError(f"litroom: unknown variant {variant!r}")
    ex = take_faceon.experiment(seed)
    config = ex.setup.projector
    fps = ex.setup.script.fps
    shown = probe_frames(ex)
    script = protocol.build_script(item, seed)
    session = session_presets(seed)[item.session]
    labels = script.labels()
    first = labels.contacts[0].t_on if labels.contacts else None
    room = litroom.room_for(variant, item, seed, script.duration, first)
    if room is not None and room.steps:  # the switch, labelled as a person making the take would (eval's recovery)
        labels = dataclasses.replace(labels, light_switches=tuple(step[0] for step in room.steps))
    hook = timed_hook(ex.light, shown, fps, faceon.TRUE_LATENCY_S, session.sensor.exposure_s)
    frames = litroom.render(script, session, item, seed, room, projected=hook)
    projector = take_faceon.stream(shown, fps, litroom.WARMUP_S, script.duration)
    return take_faceon.ProjectedTake(iter(frames), labels, projector, (config.width, config.height), fps, 0.0, room)


def probe_frames(ex: faceon._Experiment) -> Callable[[int], np.ndarray]:
    """Projector frame ``k`` of the static skin: the flat grey with the probe laid over it through ``ex``'s decoded
    map at the level of ``k``'s frame clock (8-bit, as the daemon lays it), each frame made once."""
    config = ex.setup.projector
    fps = ex.setup.script.fps
    overlay = ProbeOverlay(config, ex.calibration)
    flat = np.full((config.height, config.width), int(round(config.flat_level * 255.0)), np.uint8)
    return faceon._Cache(lambda k: overlay.lay(flat, probe_level(k / fps))[0])
