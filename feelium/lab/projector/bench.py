"""`feelium bench projector`: render time per frame at the projector's resolution on one core.

Scenes: the avatar alone, the avatar with a typical exchange's answers, and
every answer at once (the worst case), each warped in full. The baseline, measured in the same run,
is the least any renderer must do: one plain resize of the skin canvas to the
projector's resolution. The back-light prediction the touch service runs per
projector frame is measured too, from the frame (the old way) and from the skin canvas (the daemon's). Then a realistic frame stream (:mod:`feelium.lab.projector.stream`)
is warped both in full and by tiles (only what changed), frame by frame in turn.
"""

from __future__ import annotations

from typing import Any

import cv2

from feelium.interactions.answers import Answer
from feelium.projector.backlight import BacklightPredictor
from feelium.projector.canvaslight import CanvasLightPredictor
from feelium.skin.projector_map import ProjectorMap
from feelium.projector.config import ProjectorConfig
from feelium.projector.renderer import Renderer
from feelium.lab.projector.stream import FACE_FPS, run_stream
from feelium.lab.timing import time_calls

_STROKE = ((0.2, 0.3), (0.3, 0.35), (0.4, 0.33), (0.5, 0.45), (0.55, 0.6))


def _scenes() -> dict[str, list[Answer]]:
    typical = [
        Answer("ripple", 0.0, 0.5, 0.2, 1.2),
        Answer("warm_pulse", 0.0, 0.5, 0.2, 1.6),
        Answer("heart", 0.0, 0.27, 0.58, 2.0, {"from": "partner"}),
        Answer("stroke", 0.0, 0.5, 0.5, detail={"points": _STROKE}),
    ]
    everything = typical + [
        Answer("palm_glow", 0.0, 0.6, 0.75, detail={"side": "partner"}),
        Answer("palm_glow", 0.0, 0.6, 0.75, detail={"side": "wearer", "from_u": 0.5, "from_v": 0.8, "glide_s": 0.8}),
        Answer("breathing", 0.0, 0.5, 0.5),
        Answer("shimmer", 0.0, 0.5, 0.5, 6.0),
        Answer("ignite", 0.0, 0.4, 0.4, 3.0, {"strokes": (_STROKE,)}),
        Answer("prompt", 0.0, 0.5, 0.93, 4.0, {"text": "draw: cat"}),
    ]
    return {"avatar": [], "typical": typical, "everything": everything}


def run_bench(config: ProjectorConfig, calibration: ProjectorMap, frames: int = 90, stream_s: float = 10.0) -> dict[str, Any]:
    """Timings (one OpenCV thread, CPU time per frame) and ratios against the resize baseline; then
    ``stream_s`` seconds of a realistic frame stream, full against tiled warp (:mod:`.stream`)."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        renderer = Renderer(config, calibration)
        canvas = renderer.canvas(0.0, None, [])
        size = (config.width, config.height)
        baseline = time_calls(lambda i: cv2.resize(canvas, size, interpolation=cv2.INTER_LINEAR), frames)
        rows: dict[str, Any] = {"baseline_resize": baseline}
        for name, answers in _scenes().items():  # every pixel re-warped: the cost of a frame where all changed
            rows[f"render_{name}"] = time_calls(
                lambda i, a=answers: renderer.tiles.full(renderer.canvas(0.5 + i / config.fps, None, a)), frames
            )
        predictor = BacklightPredictor(config, calibration)
        frame, grey = renderer.render_with_canvas(0.5, None, _scenes()["typical"])
        rows["backlight_gain"] = time_calls(lambda i: predictor.gain(frame), frames)  # the old way, from the frame
        from_canvas = CanvasLightPredictor(config, calibration)
        rows["canvas_light"] = time_calls(lambda i: from_canvas.gain(grey), frames)  # the daemon's, from the canvas
        streams = {
            name: run_stream(Renderer(config, calibration), config.fps, stream_s, moving_face=moving)
            for name, moving in (("face_video", True), ("still_face", False))
        }
    finally:
        cv2.setNumThreads(threads)
    base = baseline["median_ms"]
    for name, row in rows.items():
        row["fps"] = round(1000.0 / row["median_ms"], 1) if row["median_ms"] > 0 else None
        row["ratio_to_baseline"] = round(row["median_ms"] / base, 2) if base > 0 else None
    return {
        "projector": {"width": config.width, "height": config.height, "target_fps": config.fps},
        "canvas": {"width": config.canvas_width, "height": config.canvas_height},
        "calibration": calibration.source,
        "threads": 1,
        "frames": frames,
        "rows": rows,
        "meets_target": rows["render_everything"]["median_ms"] <= 1000.0 / config.fps,
        "streams": streams,
    }


def format_table(report: dict[str, Any]) -> str:
    lines = [
        f"projector {report['projector']['width']}x{report['projector']['height']}, one core, "
        f"{report['frames']} frames, calibration: {report['calibration']}",
        "CPU ms of one core per frame; the wall columns are inflated when the machine is busy",
        f"{'step':<20}{'median ms':>10}{'p95 ms':>9}{'fps':>8}{'x baseline':>12}{'wall median':>13}{'wall p95':>10}",
    ]
    for name, row in report["rows"].items():
        lines.append(
            f"{name:<20}{row['median_ms']:>10.2f}{row['p95_ms']:>9.2f}{row['fps']:>8}{row['ratio_to_baseline']:>12}"
            f"{row['wall_median_ms']:>13.2f}{row['wall_p95_ms']:>10.2f}"
        )
    lines.append(f"30 fps worst case met: {report['meets_target']}")
    lines.append(
        f"frame streams ({report['projector']['target_fps']:g} fps, face video {FACE_FPS:g} fps, taps and hearts), "
        "new canvas + full warp vs Renderer.render (tiled), CPU ms of one core, malloc as the daemon's:"
    )
    lines.append(
        f"{'stream':<12}{'frames':>7}{'full med':>10}{'tiled med':>10}{'ratio':>7}"
        f"{'full ms/s':>11}{'tiled ms/s':>11}{'ratio':>7}{'dirty':>7}{'allocs':>7}{'max diff':>9}"
    )
    for name, s in report["streams"].items():
        lines.append(
            f"{name:<12}{s['frames']:>7}{s['full']['median_ms']:>10.2f}{s['tiled']['median_ms']:>10.2f}"
            f"{s['median_ratio']:>7.2f}{s['cpu_ms_per_s_full']:>11.1f}{s['cpu_ms_per_s_tiled']:>11.1f}"
            f"{s['cpu_ratio']:>7.2f}{s['dirty_fraction_mean']:>7.2f}{s['frames_allocated']:>7}{s['max_abs_difference']:>9}"
        )
    return "\n".join(lines)
