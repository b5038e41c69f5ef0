"""Thread CPU per displayed projector frame on the board bench's workload, and its growth with a drawing's strokes.

    PYTHONPATH=$PWD python3 benchmarks/projector_frame_cost.py [--seconds 20] [--strokes 0 8 64] [--json FILE]

What `feelium bench board` makes the projector do, in one thread and without the daemon around it: 30 frames a
second; the headset's looping face video (its JPEGs, 12 fps) decoded and fitted when a new one is due, as
``ProjectorService.update_face`` does; a tap every 1.5 s (ripple and warm pulse) and a wearer's heart every 2 s
(:mod:`feelium.lab.projector.stream`); and, per scenario, a drawing round of N full strokes (256 points each)
whose newest stroke gains a point every frame. Each displayed frame's cost is the thread CPU time of the face
decode (when due) and ``Renderer.render_with_canvas``; OpenCV's threads are left as the daemon leaves them (its
workers' time is not in this thread's). The first second is warm-up. The figure per scenario is the mean ms per
displayed frame; the median, p95 and frames drawn per second (the rest show the previous frame again) beside it.
For an A/B, run it from a worktree of the older commit with ``PYTHONPATH`` pointing there, back to back.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import cv2
import numpy as np

from feelium.daemon.config import Config
from feelium.daemon.memory import tune_malloc
from feelium.interactions.answers import Answer
from feelium.interactions.engine import MAX_STROKE_POINTS
from feelium.lab.projector.stream import answers_at
from feelium.projector.renderer import Renderer
from feelium.projector.service import decode_reduced
from feelium.skin.projector_map import load_or_default

FACE_FPS = 12.0
FACE_FRAMES = 24


def face_jpegs() -> list[bytes]:
    """The headset's face video in the board bench (feelium.lab.daemon.headset): a drifting texture, a pulsing disc."""
    texture = cv2.GaussianBlur(np.random.default_rng(1).integers(0, 80, (400, 520, 3), np.uint8), (0, 0), 3)
    out = []
    for i in range(FACE_FRAMES):
        dx, dy = int(20 + 15 * np.sin(i / 4)), int(20 + 15 * np.cos(i / 5))
        image = cv2.add(texture[dy : dy + 360, dx : dx + 480], 40)
        cv2.circle(image, (240, 180), 80 + 4 * (i % 6), (90, 140, 220), -1)
        out.append(cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])[1].tobytes())
    return out


def drawing(count: int, seed: int = 4) -> list[list[tuple[float, float]]]:
    """``count`` random-walk strokes of the engine's full length, rounded as the engine rounds points."""
    rng = np.random.default_rng(seed)
    walks = []
    for _ in range(count):
        p = rng.uniform(0.15, 0.85, 2)
        walk = []
        for _ in range(MAX_STROKE_POINTS):
            p = np.clip(p + rng.normal(0.0, 0.01, 2), 0.02, 0.98)
            walk.append((round(float(p[0]), 4), round(float(p[1]), 4)))
        walks.append(walk)
    return walks


def run(renderer: Renderer, jpegs: list[bytes], strokes: int, seconds: float, fps: float) -> dict[str, float]:
    walks = drawing(strokes)
    face, face_index, costs = None, -1, []
    alive: dict[tuple, Answer] = {}  # the engine hands the same answer object until it changes the answer

    def kept(answer: Answer, *key: object) -> Answer:
        return alive.setdefault((answer.kind, answer.t0, answer.u, answer.v, *key), answer)

    for i in range(int(seconds * fps)):
        now = i / fps
        answers = [kept(a) for a in answers_at(now, seed=1)]
        if walks:  # the newest stroke is being drawn: it starts short and gains a point a frame, then starts over
            live = 2 + i % (MAX_STROKE_POINTS - 2)
            number = len(walks) + i // (MAX_STROKE_POINTS - 2)
            answers += [
                kept(Answer("stroke", -1.0 - k, 0.5, 0.5, detail={"points": tuple(w), "stroke": k, "round": 1}), k)
                for k, w in enumerate(walks[:-1])
            ]
            points = tuple(walks[-1][:live])
            answers.append(kept(Answer("stroke", -0.5, 0.5, 0.5, detail={"points": points, "stroke": number, "round": 1}), number, live))
        answers.sort(key=lambda a: a.t0)  # the engine's answers(): its cost is not the projector's
        start = time.thread_time()
        due = int(now * FACE_FPS) % FACE_FRAMES
        if due != face_index:  # a new face JPEG arrived: decoded and fitted in the projector's thread
            face_index = due
            face = renderer.fit_face(decode_reduced(jpegs[due], *renderer.canvas_size))
        frame, grey = renderer.render_with_canvas(now, face, answers)
        costs.append((time.thread_time() - start) * 1e3)
        del frame, grey
    steady = np.array(costs[int(fps) :])
    return {
        "frames": int(steady.size),
        "mean_ms": round(float(steady.mean()), 3),
        "median_ms": round(float(np.median(steady)), 3),
        "p95_ms": round(float(np.percentile(steady, 95)), 3),
        "rendered_per_s": round(float(getattr(renderer, "rendered", len(costs))) / (len(costs) / fps), 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per scenario (30 fps)")
    parser.add_argument("--strokes", type=int, nargs="+", default=[0, 8, 64], help="full strokes on the skin, per scenario")
    parser.add_argument("--answer-fps", type=float, help="[projector] answer_fps (default: the config's)")
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    config = Config()
    if args.answer_fps is not None:
        config = dataclasses.replace(config, projector=dataclasses.replace(config.projector, answer_fps=args.answer_fps))
    tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)
    size = (config.projector.width, config.projector.height)
    roi = tuple(config.rear_camera.roi) if config.rear_camera.roi else None
    calibration = load_or_default(Path("/nonexistent/calibration.npz"), size, roi)  # the board bench's stand-in map
    jpegs = face_jpegs()
    results = {}
    for count in args.strokes:
        renderer = Renderer(config.projector, calibration)
        results[str(count)] = run(renderer, jpegs, count, args.seconds, config.projector.fps)
        print(f"{count:>3} strokes: {results[str(count)]}", flush=True)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump({"opencv_threads": cv2.getNumThreads(), "scenarios": results}, handle, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
