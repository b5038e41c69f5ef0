"""The back-light from the skin canvas against the one from the projector frame, and both against the simulator.

``python -m feelium.lab.projector.canvaslight_check``: the renderer's own output (the talking avatar with 0-2
answers, ``frames`` frames 0.1 s apart) through the Gray-code calibration decoded in the simulator, predicted
by :class:`BacklightPredictor` (from the 1280x720 frame, the old way) and :class:`CanvasLightPredictor` (from
the grey canvas, the daemon's), compared with each other and with the simulator's projected light over the
calibration's covered patch (and its inner part, 3 px in from the edge). Figures in docs/touch.md.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import cv2
import numpy as np

from feelium.interactions.answers import Answer
from feelium.lab.projector.facevideo import sim_calibration
from feelium.projector.backlight import BacklightPredictor
from feelium.projector.canvaslight import CanvasLightPredictor
from feelium.projector.config import ProjectorConfig
from feelium.projector.layers import DRAWERS
from feelium.projector.renderer import Renderer
from feelium.sim.projection import FisheyeWarp, ProjectedLight, ProjectorOptics

CAMERA = (640, 480)


def compare(seed: int = 1, frames: int = 30, sizes: tuple[tuple[int, int], ...] = (CAMERA, (320, 240))) -> dict[str, Any]:
    """Per frame size: mean and max abs differences (new - old; each against the simulator's light)."""
    config = ProjectorConfig()
    warp, optics = FisheyeWarp(), ProjectorOptics(flat_level=config.flat_level)
    calibration, _ = sim_calibration(seed, config, warp, optics)
    truth = ProjectedLight(warp, CAMERA, optics)
    renderer = Renderer(config, calibration)
    kinds = sorted(DRAWERS)
    shown = []
    for k in range(frames):
        now = k * 0.1
        rng = np.random.default_rng([seed, k])
        answers = [
            Answer(kinds[int(rng.integers(len(kinds)))], now - 0.3, float(rng.uniform(0.1, 0.9)), float(rng.uniform(0.1, 0.9)))
            for _ in range(k % 3)
        ]
        frame, grey = renderer.render_with_canvas(now, None, answers, talking=True)
        shown.append((frame, grey, truth.factor(frame)))
    out: dict[str, Any] = {}
    for size in sizes:
        old, new = BacklightPredictor(config, calibration, size), CanvasLightPredictor(config, calibration, size)
        covered = ~old._uncovered
        inner = cv2.distanceTransform(covered.astype(np.uint8), cv2.DIST_L2, 3) > 3.0
        rows: dict[str, list[np.ndarray]] = {"new_old": [], "old_truth": [], "new_truth": []}
        inner_rows: dict[str, list[float]] = {"old_truth": [], "new_truth": []}
        for frame, grey, light in shown:
            if size != CAMERA:
                light = cv2.resize(light, size, interpolation=cv2.INTER_AREA)
            g_old, g_new = old.gain(frame), new.gain(grey)
            for name, a, b in (("new_old", g_new, g_old), ("old_truth", g_old, light), ("new_truth", g_new, light)):
                diff = np.abs(a - b)
                rows[name].append(diff[covered])
                if name in inner_rows:
                    inner_rows[name].append(float(diff[inner].mean()))
        out[f"{size[0]}x{size[1]}"] = {
            "canvas_reduction": new.reduce,
            "blur_px": round(new.diffusion_px, 3),
            **{name: {"mean": round(float(np.mean(np.concatenate(v))), 5), "max": round(float(max(d.max() for d in v)), 4)}
               for name, v in rows.items()},
            **{f"{name}_inner_mean": round(float(np.mean(v)), 5) for name, v in inner_rows.items()},
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--frames", type=int, default=30)
    args = parser.parse_args(argv)
    print(json.dumps(compare(args.seed, args.frames), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
