"""How little projected light a press needs to be seen (issue 17, point 1: the face-on fades).

With the face on, every miss left was a tap landing while the wearer's video
was faded to black, i.e. while the skin was lit by the projector's sensing
floor alone. A pressed fingertip is told from a close hover by the *projector*
light it takes away (the frustrated reflection) and by its sharp edge; room
light is blocked alike by both. So a press's depth falls with the projected
light present, and below some light no depth gate can take it without taking
hovers. This sweep measures where: the face experiment's world
(:mod:`feelium.lab.touch.faceon`, the same trials, hands, noise, latency and
warm-up), except that the wearer's video fades to black 1 s before each trial
and stays black, so the whole trial is lit by ``[projector] sensing_floor``;
the floor is swept. Only the daemon's path (``face_compensated``) is replayed.
For each floor it reports the projected light on the patch (relative to the
flat grey the gates were calibrated under: the predicted back-light's median
over the ROI), the recall of the touch trials, the negatives that fired and
the gates' margins.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from feelium.lab.report import finish_experiment, print_progress
from feelium.lab.touch.faceon import FaceScript, FaceVideo, _Experiment, _Setup, run_experiment
from feelium.projector.config import ProjectorConfig
from feelium.sim.scene import ROI
from feelium.touch.config import TouchConfig

FLOORS = (0.45, 0.55, 0.65, 0.75)
LABELS = ("tap", "hold", "hover")
BLACK_FROM_S = -1.0  # the video is black from 1 s before the trial (the warm-up saw the face before that)


def patch_light(floor: float, seed: int = 1) -> float:
    """Median predicted light over the ROI (flat grey = 1) of a black video shown with ``floor``."""
    script = FaceScript(black_from_s=BLACK_FROM_S)
    ex = _Experiment(_Setup(seed, replace(ProjectorConfig(), sensing_floor=floor), TouchConfig(), script))
    gain = ex.predictor.gain(FaceVideo(ex.renderer, ex.source, script, 0.0).frame(0))
    x, y, w, h = ROI
    return float(np.median(gain[y : y + h, x : x + w]))


def sweep(
    *,
    floors: tuple[float, ...] = FLOORS,
    scale: float = 0.2,
    seed: int = 1,
    labels: tuple[str, ...] = LABELS,
    jobs: int = 1,
    progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, Any]:
    """One face-experiment run per sensing floor, the video held black through every trial."""
    rows = []
    for floor in floors:
        report = run_experiment(
            scale=scale,
            seed=seed,
            projector=replace(ProjectorConfig(), sensing_floor=floor),
            script=FaceScript(black_from_s=BLACK_FROM_S),
            labels=labels,
            conditions=("face_compensated",),
            jobs=jobs,
            progress=progress,
        )
        rows.append({"sensing_floor": floor, "light": patch_light(floor, seed), **report["conditions"]["face_compensated"]})
    return {"scale": scale, "seed": seed, "labels": list(labels), "rows": rows}


def format_table(report: dict[str, Any]) -> str:
    lines = [
        f"sensing-floor sweep, video black: scale {report['scale']}, seed {report['seed']}, {'/'.join(report['labels'])}",
        f"{'floor':>6}{'light':>7}{'recall':>8}{'tp/n':>7}{'neg fired':>11}"
        + "".join(f"{gate + ' neg/pos margin':>26}" for gate in ("edge", "instant", "sustained")),
    ]

    def num(v: float | None) -> str:
        return "-" if v is None else f"{v:+.3f}"

    for r in report["rows"]:
        g = r["margins"]
        lines.append(
            f"{r['sensing_floor']:>6.2f}{r['light']:>7.2f}{r['recall'] if r['recall'] is not None else float('nan'):>8.3f}"
            f"{r['tp']:>4}/{r['tp'] + r['fn']:<2}{r['negatives_fired']:>6} / {r['negatives']:<3}"
            + "".join(f"{num(g[gate]['negative_margin']):>13}{num(g[gate]['positive_margin']):>13}" for gate in g)
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m feelium.lab.touch.dimlight [--floors 0.45,0.6] [--scale S] [--jobs N] [--json FILE]``."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m feelium.lab.touch.dimlight", description=__doc__.splitlines()[0])
    parser.add_argument("--floors", default=",".join(str(f) for f in FLOORS), help="sensing floors, comma-separated")
    parser.add_argument("--scale", type=float, default=0.2)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--labels", default=",".join(LABELS))
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--json", help="write the report here")
    args = parser.parse_args(argv)
    report = sweep(
        floors=tuple(float(f) for f in args.floors.split(",")),
        scale=args.scale,
        seed=args.seed,
        labels=tuple(args.labels.split(",")),
        jobs=args.jobs,
        progress=print_progress,
    )
    return finish_experiment(format_table(report), report, args.json)


if __name__ == "__main__":
    raise SystemExit(main())
