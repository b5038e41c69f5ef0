"""Touches over the whole front face, scored by zone (issue 17, point 3).

The paper touched one rectangle; a blimp is touched anywhere on its front.
This bench renders the protocol's taps, holds, swipes and hovers at targets
spread over the whole curved face (:class:`feelium.skin.face.FaceModel`,
:meth:`feelium.sim.scene.SceneRenderer` with ``face``), replays them through
the real pipeline with the same face model, and reports per zone:

- ``centre``: the face within a third of its half-extent of the front axis,
- ``mid``: a third to two thirds,
- ``edge``: two thirds to :data:`EDGE_MAX` (the rim, where the back-light is
  dimmest and a hand's scale in pixels differs most from the centre's),

with the zone taken as ``max(|u - 0.5|, |v - 0.5|) / 0.5`` of the target.
Per zone: trial recall, negatives (hovers) fired, false touches (touches
outside every widened contact, in any trial), localisation error of the
landing in camera pixels and in mm along the membrane (the great circle
between the reported and the true skin point; taps and holds, as `feelium
eval` scores it, and the swipes' landings apart: a moving finger), and the
zone's local scale and back-light level. Every parameter is stated below or
in :mod:`feelium.skin.face`, none was chosen from detector scores; the
``[touch]`` settings are the shipped defaults, with the working resolution
chosen so a working pixel covers the same membrane as on the paper's protocol
(:data:`WORK`).
"""

from __future__ import annotations

import math
import multiprocessing
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from feelium.events import TouchEvent
from feelium.lab.report import finish_experiment, print_progress
from feelium.lab.sim import protocol, scripts
from feelium.lab.touch.zones import ZONE_CUTS, ZONES
from feelium.lab.touch.evaluate import WIDEN_AFTER_S, WIDEN_BEFORE_S, TrialData, group_touches, score_trials
from feelium.sim.camera import frame_times
from feelium.sim.scene import SceneRenderer, exposure_samples
from feelium.sim.sessions import SESSION_NAMES, session_presets
from feelium.skin.face import FaceModel
from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline

FRAME = (1280, 960)  # the rear camera's frame: with the face filling it, ~2 px/mm at the centre, the protocol's scale
WORK = (640, 480)  # working resolution: 1 working px per mm at the centre, as 320x240 of the protocol's 640x480
EDGE_MAX = 0.92  # targets stay this far out at most: a fingertip pad (~12 mm) lands wholly on the face
ZONE_RANGE = {"centre": (0.0, ZONE_CUTS[0]), "mid": ZONE_CUTS, "edge": (ZONE_CUTS[1], EDGE_MAX)}
LABELS = ("tap", "hold", "swipe", "hover")
BUILDERS = {"tap": scripts.tap, "hold": scripts.hold, "swipe": scripts.swipe, "hover": scripts.hover}
AIM_PX = 4.0  # the partner misses the drawn target by this much (sd, px)
BOX_HALF_UV = 0.18  # a swipe and the hand's landing are kept inside this much u, v around the target


def face_model() -> FaceModel:
    """The bench's face: the shipped geometry (64 cm sphere, camera 240 mm behind the centre) filling :data:`FRAME`."""
    return FaceModel.for_frame(*FRAME)


def zone_of(u: float, v: float) -> str | None:
    """The zone of skin point ``(u, v)`` (None off the bench's face)."""
    rho = max(abs(u - 0.5), abs(v - 0.5)) / 0.5
    for zone in ZONES:
        lo, hi = ZONE_RANGE[zone]
        if lo <= rho < hi or (zone == "centre" and rho == 0.0):
            return zone
    return None


def draw_target(rng: np.random.Generator, zone: str) -> tuple[float, float]:
    """A skin point drawn uniformly in u, v over ``zone`` (rejection from the square it lies in)."""
    lo, hi = ZONE_RANGE[zone]
    while True:
        a, b = rng.uniform(-hi, hi, 2)
        if lo <= max(abs(a), abs(b)) < hi:
            return 0.5 + 0.5 * float(a), 0.5 + 0.5 * float(b)


def local_box(face: FaceModel, u: float, v: float) -> tuple[int, int, int, int]:
    """A camera-pixel box around skin ``(u, v)`` that lies on the face: where a trial's hand may land and slide."""
    u0, u1 = max(0.02, u - BOX_HALF_UV), min(0.98, u + BOX_HALF_UV)
    v0, v1 = max(0.02, v - BOX_HALF_UV), min(0.98, v + BOX_HALF_UV)
    s = np.linspace(0.0, 1.0, 41)
    left, _ = face.to_camera(np.full_like(s, u0), v0 + (v1 - v0) * s)
    right, _ = face.to_camera(np.full_like(s, u1), v0 + (v1 - v0) * s)
    _, top = face.to_camera(u0 + (u1 - u0) * s, np.full_like(s, v0))
    _, bottom = face.to_camera(u0 + (u1 - u0) * s, np.full_like(s, v1))
    x0, x1 = float(left.max()), float(right.min())
    y0, y1 = float(top.max()), float(bottom.min())
    return int(math.ceil(x0)), int(math.ceil(y0)), int(x1 - x0), int(y1 - y0)


@dataclass(frozen=True)
class Trial:
    """One planned trial: its name (the RNG streams' key), zone, label and session."""

    name: str
    zone: str
    label: str
    session: str


def plan(per_cell: int) -> list[Trial]:
    """``per_cell`` trials of every label in every zone, sessions round-robin."""
    out = []
    for zone in ZONES:
        for label in LABELS:
            for i in range(per_cell):
                out.append(Trial(f"face-{zone}-{label}-{i + 1:03d}", zone, label, SESSION_NAMES[i % len(SESSION_NAMES)]))
    return out


def build_script(face: FaceModel, trial: Trial, seed: int) -> tuple[scripts.Script, tuple[float, float]]:
    """The trial's script (the protocol's builders, aimed at a target drawn in its zone) and the target's u, v."""
    rng = protocol.recording_rng(seed, trial.name, 0)
    u, v = draw_target(rng, trial.zone)
    x, y = face.to_camera(u, v)
    aim = (float(rng.normal(0.0, AIM_PX)), float(rng.normal(0.0, AIM_PX)))
    return BUILDERS[trial.label](rng, (float(x), float(y)), aim, local_box(face, u, v)), (u, v)


@dataclass
class Result:
    """What one trial gave: its scoring data and the landing's error (positives that were detected)."""

    trial: Trial
    target_uv: tuple[float, float]
    data: TrialData
    false_touches: int
    error_px: float | None
    error_mm: float | None
    px_per_mm: float
    light: float  # back-light at the target relative to the face's brightest


def _false_touches(events: list[TouchEvent], data: TrialData) -> int:
    windows = [(c.t_on - WIDEN_BEFORE_S, c.t_off + WIDEN_AFTER_S) for c in data.labels.contacts]
    return sum(1 for t in group_touches(events) if not any(t.t_on <= w1 and t.t_off >= w0 for w0, w1 in windows))


def _landing_error(face: FaceModel, data: TrialData) -> tuple[float | None, float | None]:
    """Pixels and mm on the membrane between the first matched touch's landing and the true fingertip then."""
    touches = group_touches(data.events)
    for contact in data.labels.contacts:
        w0, w1 = contact.t_on - WIDEN_BEFORE_S, contact.t_off + WIDEN_AFTER_S
        hits = [t for t in touches if t.t_on <= w1 and t.t_off >= w0]
        if not hits:
            continue
        touch = hits[0]
        truth = contact.position_at(touch.t_on)
        if truth is None:
            continue
        px = float(math.hypot(touch.x - truth[0], touch.y - truth[1]))
        (tu, tv), (gu, gv) = face.to_uv(touch.x, touch.y), face.to_uv(truth[0], truth[1])
        return px, float(face.distance_mm(tu, tv, gu, gv))
    return None, None


@dataclass(frozen=True)
class _Setup:
    seed: int
    touch: TouchConfig


def run_trial(setup: _Setup, trial: Trial, face: FaceModel) -> Result:
    """Render one trial on the face and replay it through the pipeline with the same face model."""
    script, (u, v) = build_script(face, trial, setup.seed)
    session = session_presets(setup.seed)[trial.session]
    rng = protocol.recording_rng(setup.seed, trial.name, 1)
    roi = face.roi()
    scene = SceneRenderer(session, rng, roi=roi, face=face)
    pipeline = TouchPipeline(setup.touch, FRAME, roi, face=face)
    events: list[TouchEvent] = []
    activity, max_area = False, 0.0
    for t in frame_times(session.sensor, script.duration, rng):
        frame = scene.frame(float(t), exposure_samples(script.state, float(t), session.sensor.exposure_s))
        result = pipeline.process(float(t), frame)
        events.extend(result.events)
        activity |= result.activity
        max_area = max(max_area, float(result.area))
    events.extend(pipeline.finish())
    data = TrialData(trial.name, script.labels(), events, activity, max_area)
    err_px, err_mm = _landing_error(face, data) if data.labels.contacts else (None, None)
    x, y = (int(round(float(c))) for c in face.to_camera(u, v))
    light = float(scene.backlight[y, x] / scene.backlight[face.mask()].max())
    return Result(trial, (u, v), data, _false_touches(events, data), err_px, err_mm, float(face.px_per_mm(u, v)), light)


_SETUP: _Setup | None = None
_FACE: FaceModel | None = None


def _init_worker(setup: _Setup) -> None:
    global _SETUP, _FACE
    cv2.setNumThreads(1)
    _SETUP, _FACE = setup, face_model()


def _worker(trial: Trial) -> Result:
    assert _SETUP is not None and _FACE is not None
    return run_trial(_SETUP, trial, _FACE)


def _stats(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    a = np.asarray(values, float)
    return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)), "max": float(a.max()), "n": int(a.size)}


def summarise(results: list[Result]) -> dict[str, Any]:
    """One zone's figures (or all zones')."""
    trials = score_trials([r.data for r in results])["trials"]
    still = [r for r in results if r.trial.label in ("tap", "hold")]
    return {
        "trials": len(results),
        "recall": trials["recall"],
        "tp": trials["tp"],
        "fn": trials["fn"],
        "negatives_fired": trials["fp"],
        "negatives": trials["fp"] + trials["tn"],
        "false_touches": sum(r.false_touches for r in results),
        "localisation_px": _stats([r.error_px for r in still if r.error_px is not None]),
        "localisation_mm": _stats([r.error_mm for r in still if r.error_mm is not None]),
        "swipe_landing_px": _stats([r.error_px for r in results if r.trial.label == "swipe" and r.error_px is not None]),
        "px_per_mm": {"min": min(r.px_per_mm for r in results), "max": max(r.px_per_mm for r in results)},
        "backlight": {"min": min(r.light for r in results), "max": max(r.light for r in results)},
        "by_label": trials["by_label"],
        "missed": [r.trial.name for r in results if r.trial.label in ("tap", "hold", "swipe") and r.error_px is None],
        "fired": [r.trial.name for r in results if r.trial.label == "hover" and group_touches(r.data.events)],
    }


def run_experiment(
    *,
    per_cell: int = 3,
    seed: int = 1,
    touch: TouchConfig | None = None,
    jobs: int = 1,
    progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, Any]:
    """Every zone x label cell ``per_cell`` times; the report (per zone and over the whole face)."""
    setup = _Setup(seed, touch or replace(TouchConfig(), width=WORK[0], height=WORK[1]))
    trials = plan(per_cell)
    results: list[Result] = []

    def collect(stream: Iterator[Result]) -> None:
        for n, result in enumerate(stream, start=1):
            results.append(result)
            if progress is not None:
                progress(n, len(trials), result.trial.name)

    if jobs <= 1:
        face = face_model()
        collect(run_trial(setup, t, face) for t in trials)
    else:
        spawn = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker, initargs=(setup,), mp_context=spawn) as pool:
            collect(pool.map(_worker, trials))
    face = face_model()
    return {
        "seed": seed,
        "per_cell": per_cell,
        "frame": list(FRAME),
        "work": [setup.touch.width, setup.touch.height],
        "face": face.to_json(),
        "roi": list(face.roi()),
        "zones": {z: summarise([r for r in results if r.trial.zone == z]) for z in ZONES},
        "all": summarise(results),
        "trials": [_row(r) for r in results],
    }


def _row(r: Result) -> dict[str, Any]:
    """One trial in the report: where it was aimed and what came out."""
    return {
        "name": r.trial.name,
        "session": r.trial.session,
        "uv": [round(r.target_uv[0], 4), round(r.target_uv[1], 4)],
        "touches": len(group_touches(r.data.events)),
        "false_touches": r.false_touches,
        "error_px": r.error_px,
        "error_mm": r.error_mm,
        "px_per_mm": r.px_per_mm,
        "backlight": r.light,
    }


def format_table(report: dict[str, Any]) -> str:
    def num(v: float | None, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    lines = [
        f"whole face: {report['all']['trials']} trials ({report['per_cell']} per zone x label, seed {report['seed']})",
        f"{'zone':<8}{'recall':>8}{'neg fired':>11}{'false':>7}{'loc px med/p95':>16}{'loc mm med/p95':>16}"
        f"{'swipe px med/max':>18}{'px/mm':>12}{'back-light':>12}",
    ]
    for name, z in [*report["zones"].items(), ("all", report["all"])]:
        px, mm = z["localisation_px"], z["localisation_mm"]
        locs = "-" if px is None else f"{px['median']:.2f} / {px['p95']:.2f}"
        locm = "-" if mm is None else f"{mm['median']:.2f} / {mm['p95']:.2f}"
        sw = z["swipe_landing_px"]
        swipe = "-" if sw is None else f"{sw['median']:.2f} / {sw['max']:.2f}"
        scale = f"{z['px_per_mm']['min']:.2f}-{z['px_per_mm']['max']:.2f}"
        light = f"{z['backlight']['min']:.2f}-{z['backlight']['max']:.2f}"
        lines.append(
            f"{name:<8}{num(z['recall'], '.3f'):>8}{z['negatives_fired']:>6} / {z['negatives']:<3}{z['false_touches']:>7}"
            f"{locs:>16}{locm:>16}{swipe:>18}{scale:>12}{light:>12}"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m feelium.lab.touch.face_zones [--per-cell N] [--seed S] [--jobs J] [--json FILE]``."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m feelium.lab.touch.face_zones", description=__doc__.splitlines()[0])
    parser.add_argument("--per-cell", type=int, default=3, help="trials per zone and label (default 3: 36 trials)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--json", help="write the report here")
    args = parser.parse_args(argv)
    report = run_experiment(
        per_cell=args.per_cell,
        seed=args.seed,
        jobs=args.jobs,
        progress=print_progress,
    )
    return finish_experiment(format_table(report), report, args.json)


if __name__ == "__main__":
    raise SystemExit(main())
