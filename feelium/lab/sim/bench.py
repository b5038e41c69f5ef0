"""`feelium bench sim`: render time per 640x480 frame of the scene simulator, by scene.

The baseline, measured in the same run, is the least any frame costs: the
static back-lit membrane with banding, gain and sensor noise (an empty scene).
Each other scene adds shadows: a still pressed hand, a wobbling hover, a fast
swipe (motion blur sub-samples), a sweeping open hand and a body. FFV1
encoding of a frame is measured too, since writing a dataset pays it per frame.
CPU time of this thread is reported (robust on a busy machine) next to wall time.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from feelium.recording import RecordingWriter
from feelium.sim.hand import Blob, HandPose
from feelium.sim.hand_paths import HandTrack, Keyframe, Tremor
from feelium.sim.sessions import session_presets
from feelium.sim.scene import HEIGHT, ROI, WIDTH, SceneRenderer, SceneState, exposure_samples
from feelium.lab.timing import time_calls


def _scenes() -> dict[str, Callable[[float], SceneState]]:
    hover = HandTrack(keys=(Keyframe(0.0, 320, 240, 3.0),), tremor=Tremor.draw(np.random.default_rng(0), drift_mm=0.5))
    sweep = HandTrack(
        keys=(Keyframe(0.0, 0, 240, 30.0), Keyframe(2.0, 640, 240, 30.0)), open_hand=True, heading=0.0,
        tremor=Tremor.draw(np.random.default_rng(1)),
    )  # fmt: skip
    swipe = HandTrack(keys=(Keyframe(0.0, 200, 240, 0.0), Keyframe(2.0, 440, 240, 0.0)), contacts=((0.0, 2.0),))
    return {
        "empty (baseline)": lambda t: SceneState(),
        "pressed": lambda t: SceneState(hands=(HandPose(320, 240, 0.0),)),
        "hover": lambda t: SceneState(hands=(hover.pose(t),)),
        "swipe": lambda t: SceneState(hands=(swipe.pose(t % 2.0),)),
        "sweep": lambda t: SceneState(hands=(sweep.pose(t % 2.0),)),
        "body": lambda t: SceneState(blobs=(Blob(100 + 200 * (t % 2.0), 240, 180, 220, 250.0),)),
    }


def run_bench(frames: int = 60, seed: int = 1) -> dict[str, Any]:
    """Per-frame render times by scene, their ratio to the empty baseline, and FFV1 encoding.

    OpenCV runs single-threaded here so the thread's CPU time is all the work done.
    """
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        return _run(frames, seed)
    finally:
        cv2.setNumThreads(threads)


def _run(frames: int, seed: int) -> dict[str, Any]:
    session = session_presets(seed)["s1"]
    renderer = SceneRenderer(session, np.random.default_rng(seed))
    exposure = session.sensor.exposure_s
    results: dict[str, Any] = {}
    for name, state_at in _scenes().items():
        results[name] = time_calls(
            lambda i, f=state_at: renderer.frame(i / 15.0, exposure_samples(f, i / 15.0, exposure)), frames
        )
    base = results["empty (baseline)"]["median_ms"]
    for stats in results.values():
        stats["ratio"] = round(stats["median_ms"] / base, 2) if base > 0 else None
    sample = renderer.frame(0.0, SceneState(hands=(HandPose(320, 240, 0.0),)))
    with tempfile.TemporaryDirectory() as tmp:
        writer = RecordingWriter(Path(tmp) / "bench", name="bench", width=WIDTH, height=HEIGHT, fps=15.0, roi=ROI)
        encode = time_calls(lambda i: writer.add_frame(i / 15.0, sample), frames)
        writer.abort()
    encode["ratio"] = round(encode["median_ms"] / base, 2) if base > 0 else None
    return {"width": WIDTH, "height": HEIGHT, "frames": frames, "scenes": results, "ffv1_encode": encode}


def format_table(report: dict[str, Any]) -> str:
    rows = [f"scene simulator, {report['width']}x{report['height']}, {report['frames']} frames per scene (CPU ms of one core)"]
    rows.append(f"{'scene':<18} {'median':>8} {'p95':>8} {'wall med':>9} {'x base':>7}")
    for name, s in [*report["scenes"].items(), ("ffv1 encode", report["ffv1_encode"])]:
        rows.append(f"{name:<18} {s['median_ms']:>8.2f} {s['p95_ms']:>8.2f} {s['wall_median_ms']:>9.2f} {s['ratio']:>7.2f}")
    return "\n".join(rows)
