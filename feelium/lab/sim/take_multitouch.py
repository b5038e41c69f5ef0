"""One scene of two hands, a palm or a hug, as a labelled recording (issue 17, point 4).

The scenes are the scene bench's (:mod:`feelium.lab.touch.multitouch`: sizes physical and stated there, the
place jittered by up to 15 px), rendered the same way (a hand-free warm-up, recorded here as frames before
0 s) from the same RNG stream per scene, run and session, so a recording replays to the bench's events.
Each true contact becomes one entry of ``labels.json``'s ``contacts`` with its ``path`` (the true footprint's
centre every camera frame, area-weighted over its ellipses) and the optional ``"contact"`` kind
(``finger``/``palm``/``hug``), which ``feelium eval`` scores contact by contact
(:mod:`feelium.lab.touch.contact_score`). The trial's ``label`` is the gesture its longest contact performs
(:func:`feelium.lab.touch.contact_score.gesture_of`: the tracker's own rule applied to the true contact), its ``target`` null. Why the longest:
the spec scores a trial's kind by the event that overlaps its contacts longest, which is that contact's. Before
session 19 every scene was labelled ``hold``; recordings written then keep that label.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from feelium.lab.touch import multitouch
from feelium.lab.touch.contact_score import gesture_of
from feelium.recording import Contact, Labels
from feelium.sim.camera import frame_times
from feelium.sim.scene import ROI, SceneRenderer, SceneState, exposure_samples
from feelium.sim.sessions import SESSION_NAMES, session_presets

VARIANTS = multitouch.SCENES
RUNS_AT_SCALE_1 = 6  # two runs per session, as the bench's table (--reps 2)


@dataclass(frozen=True)
class Run:
    """One run of a scene: ``rep`` and session index ``k`` key its RNG, as in the bench."""

    scene: str
    rep: int
    k: int

    @property
    def session(self) -> str:
        return SESSION_NAMES[self.k]

    @property
    def name(self) -> str:
        return f"{self.scene}-{self.session}-{self.rep + 1:03d}"


def runs(scene: str, scale: float) -> list[Run]:
    """The runs of ``scene`` at ``scale``: at least one, round-robin over the sessions."""
    n = max(1, int(round(RUNS_AT_SCALE_1 * scale)))
    return [Run(scene, i // len(SESSION_NAMES), i % len(SESSION_NAMES)) for i in range(n)]


def render(run: Run, seed: int) -> tuple[Iterator[tuple[float, np.ndarray]], Labels]:
    """The camera frames (warm-up first) and the labels of ``run``."""
    session = session_presets(seed)[run.session]
    rng = np.random.default_rng([seed, zlib.crc32(run.scene.encode()), run.rep, run.k])
    scene = multitouch._scene(run.scene, rng)
    renderer = SceneRenderer(session, rng, roi=ROI)
    fps = session.sensor.fps
    # The bench's order of draws: the warm-up's camera noise first, then the frame times.
    warmup = [(float(t), renderer.frame(float(t), SceneState())) for t in np.arange(-multitouch.WARMUP_S, -0.25, 1.0 / fps)]
    times = [float(t) for t in frame_times(session.sensor, scene.duration, rng)]
    px_per_mm = session.shadow.px_per_mm
    contacts = []
    for truth in scene.truths:
        ts = [t for t in times if truth.on <= t < truth.off] or [truth.on]
        path = [[t, *scene.centre(truth, t, px_per_mm)[:2]] for t in ts]
        contacts.append(Contact(truth.on, truth.off, np.asarray(path, float), truth.kind))
    longest = max(contacts, key=lambda c: c.t_off - c.t_on)  # the first of equals
    labels = Labels(gesture_of(longest), False, None, tuple(contacts))

    def frames() -> Iterator[tuple[float, np.ndarray]]:
        yield from warmup
        for t in times:
            yield t, renderer.frame(t, exposure_samples(scene.state, t, session.sensor.exposure_s))

    return frames(), labels
