"""A projector-calibration recording from the simulator, with the projector on its own clock and a true latency.

``feelium calibrate projector --sim --record`` shows a pattern and captures the next frame at once: no
projector frame clock, no latency, no exposure straddling a switch, so nothing in it says how late the
light is. A real projector runs at its own rate, lights the membrane some latency after its frame clock,
and the rear camera (not locked to it) integrates over its exposure whatever was lit: a camera frame that
integrates a pattern switch mixes the two patterns in proportion to overlap. This take is that world, built
from the simulator's own physics (:func:`feelium.sim.projection.timed_hook`, the one the face-on takes use):
each pattern is held ``hold`` to ``hold + 3`` projector refreshes (drawn per pattern: the camera is not locked to
the projector, so its frames meet the switches at varied phases; a 60 Hz display and a 15 fps camera locked
together would meet them at four phases only), the recorded stream holds each pattern once with the time
the projector's frame clock showed it (as the daemon stamps the frames it hands the display), the camera's
frames come at the session's own times (jitter and drops, :func:`feelium.sim.camera.frame_times`), and the
camera's exposure is written in the meta (``camera.exposure_s``) as a blimp's recorder knows it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from feelium.lab.projector.from_recording import PURPOSE
from feelium.recording import RecordingWriter
from feelium.sim.camera import frame_times
from feelium.sim.projection import FisheyeWarp, ProjectedLight, timed_hook
from feelium.sim.scene import HEIGHT, ROI, WIDTH, SceneRenderer, SceneState, Session


def write_latency_take(
    path: Path,
    patterns: Sequence[np.ndarray],
    latency_s: float,
    *,
    hold: int = 8,
    projector_fps: float = 60.0,
    seed: int = 1,
    session: Session | None = None,
) -> Path:
    """Write the calibration recording of ``patterns`` (gray uint8, the projector's size), each held ``hold`` to
    ``hold + 3`` refreshes of a ``projector_fps`` display.

    The light of projector refresh ``k`` (shown at ``k / projector_fps``) reaches the membrane ``latency_s`` later;
    the camera starts a random fraction of a frame after the projector. Returns the finished recording's path."""
    session = session if session is not None else Session("projector-calibration")
    rng = np.random.default_rng([seed, 0x1A7])
    light = ProjectedLight(FisheyeWarp(), (WIDTH, HEIGHT))
    sensor = session.sensor
    first = np.concatenate([[0], np.cumsum(rng.integers(hold, hold + 4, len(patterns)))])  # each pattern's first refresh

    def pattern_at(k: int) -> np.ndarray:
        return patterns[min(max(int(np.searchsorted(first, k, side="right")) - 1, 0), len(patterns) - 1)]

    hook = timed_hook(light, pattern_at, projector_fps, latency_s, sensor.exposure_s)
    renderer = SceneRenderer(session, rng, projected=hook)
    duration = float(first[-1]) / projector_fps
    start = float(rng.uniform(0.0, 1.0 / sensor.fps))
    ph, pw = patterns[0].shape
    writer = RecordingWriter(
        path, name=path.name, width=WIDTH, height=HEIGHT, fps=sensor.fps, session=session.name, source="synthetic",
        roi=ROI, extra_meta={"purpose": PURPOSE, "generator": {"true_latency_s": latency_s, "hold": hold, "seed": seed}},
        exposure_s=sensor.exposure_s,
    )  # fmt: skip
    writer.set_projector(pw, ph, projector_fps)
    for k, pattern in zip(first, patterns):
        writer.add_projector_frame(float(k) / projector_fps, pattern)
    for t in frame_times(sensor, duration - start, rng, start_s=start):
        writer.add_frame(float(t), renderer.frame(float(t), SceneState()))
    return writer.close()
