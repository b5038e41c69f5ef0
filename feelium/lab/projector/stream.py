"""A realistic projector frame stream, rendered with the full warp and with the tiled warp side by side.

What the daemon renders in a minute of use: 30 projector frames per second;
the wearer's face either a video at 12 fps whose every pixel changes between
its frames (a live face: head motion, sensor noise; the worst case for the
tiled warp) or a still image; a tap every 1.5 s at a random spot (a ripple
and a warm pulse, the greeting pat's answer) and a heart from the wearer
every 2 s on a cheek. Each frame is rendered both ways in turn, so both
paths see the same machine load, and the frames are compared.
"""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from feelium.interactions.answers import Answer
from feelium.interactions.engine import HEART_S, PULSE_S, RIPPLE_S
from feelium.projector.avatar import Avatar
from feelium.projector.renderer import Renderer

FACE_FPS = 12.0
FACE_FRAMES = 24
TAP_EVERY_S = 1.5
HEART_EVERY_S = 2.0


def face_video(renderer: Renderer, seed: int) -> list[np.ndarray]:
    """Canvas-sized face frames that differ everywhere: the talking avatar over a drifting texture,
    through JPEG at the quality a headset sends (its blocking noise changes too)."""
    rng = np.random.default_rng(seed)
    cw, ch = renderer.canvas_size
    avatar = Avatar(480, 360)
    texture = cv2.GaussianBlur(rng.integers(0, 60, (400, 520, 3), np.uint8), (0, 0), 3)
    frames = []
    for k in range(FACE_FRAMES):
        dx, dy = int(20 + 15 * np.sin(k / 4)), int(20 + 15 * np.cos(k / 5))
        image = cv2.add(avatar.render(k / FACE_FPS, talking=True), texture[dy : dy + 360, dx : dx + 480])
        jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])[1]
        frames.append(renderer.fit_face(cv2.imdecode(jpeg, cv2.IMREAD_COLOR)))
    return frames


def answers_at(now: float, seed: int) -> list[Answer]:
    """The answers alive at ``now``: taps every ``TAP_EVERY_S`` at seeded random spots, wearer hearts."""
    out = []
    for k in range(int(now // TAP_EVERY_S), -1, -1):
        t0 = k * TAP_EVERY_S
        if now - t0 > max(RIPPLE_S, PULSE_S):
            break
        u, v = np.random.default_rng((seed, k)).uniform(0.15, 0.85, 2)
        out += [Answer("ripple", t0, float(u), float(v), t0 + RIPPLE_S), Answer("warm_pulse", t0, float(u), float(v), t0 + PULSE_S)]
    for k in range(int(now // HEART_EVERY_S), -1, -1):
        t0 = k * HEART_EVERY_S
        if now - t0 > HEART_S:
            break
        out.append(Answer("heart", t0, 0.27 if k % 2 else 0.73, 0.58, t0 + HEART_S, {"from": "wearer"}))
    return out


def run_stream(renderer: Renderer, fps: float, seconds: float, moving_face: bool, seed: int = 1) -> dict[str, Any]:
    """CPU ms (this thread) per frame of the straightforward render (a new canvas, every pixel warped into a
    new frame) and of :meth:`Renderer.render` (reused canvas, tiled warp, pooled frames), interleaved frame by
    frame on one renderer each; CPU per second at ``fps`` both ways and the largest pixel difference."""
    faces = face_video(renderer, seed)
    straightforward = Renderer(renderer.config, renderer.calibration)
    full_ms, tiled_ms, dirty, worst = [], [], [], 0
    for i in range(int(seconds * fps)):
        now = i / fps
        face = faces[int(now * FACE_FPS) % FACE_FRAMES] if moving_face else faces[0]
        answers = answers_at(now, seed)
        start = time.thread_time()
        reference = straightforward.tiles.full(straightforward.canvas(now, face, answers))
        mid = time.thread_time()
        frame = renderer.render(now, face, answers)
        end = time.thread_time()
        full_ms.append((mid - start) * 1e3)
        tiled_ms.append((end - mid) * 1e3)
        dirty.append(renderer.tiles.last_dirty_fraction)
        worst = max(worst, int(np.abs(frame.astype(np.int16) - reference).max()))
        del frame, reference  # as the daemon's consumers do: the pool may reuse the buffer

    def stats(values: list[float]) -> dict[str, float]:
        return {"median_ms": round(float(np.median(values)), 3), "mean_ms": round(float(np.mean(values)), 3)}

    return {
        "frames": len(full_ms),
        "full": stats(full_ms),
        "tiled": stats(tiled_ms),
        "median_ratio": round(float(np.median(tiled_ms) / np.median(full_ms)), 3),
        "cpu_ms_per_s_full": round(float(np.mean(full_ms) * fps), 1),
        "cpu_ms_per_s_tiled": round(float(np.mean(tiled_ms) * fps), 1),
        "cpu_ratio": round(float(np.mean(tiled_ms) / np.mean(full_ms)), 3),
        "dirty_fraction_mean": round(float(np.mean(dirty)), 3),
        "frames_allocated": renderer.tiles.allocated,
        "max_abs_difference": worst,
    }
