"""Does a moving projected face fool the touch sensor? The face-video robustness experiment.

The projector is the membrane's back-light, so a talking face (a mouth that
opens, eyes that blink, a head that sways) darkens and brightens spots of the
skin the way a shadow does. The experiment renders protocol trials (taps,
holds, swipes, hovers, disturbances, empty scenes, from the simulator's
protocol) three times, with the same hands, noise and sessions:

- ``flat``: the projector shows the flat grey the touch reference expects (the baseline);
- ``face``: the talking avatar plays, the touch pipeline is not told;
- ``face_predicted``: the avatar plays and the pipeline divides out the
  back-light predicted from the frame being projected, through a calibration
  recovered by the Gray-code procedure (not the simulator's true warp).

Trials are scored by the touch pipeline's own evaluation
(`feelium.lab.touch.evaluate.score_trials`, the evaluation spec's rules: a touch
trial is detected when an event overlaps a labelled contact widened to
[t_on - 0.2 s, t_off + 0.5 s]; any event in a negative trial is a false
positive). Trial-level counts hide a second contact in a trial that already
fired, so every emitted touch outside the widened labelled contacts is also
counted as a *false touch*.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from feelium.events import TouchEvent
from feelium.projector.backlight import BacklightPredictor
from feelium.lab.projector.calibrate import run_calibration
from feelium.skin.projector_map import ProjectorMap
from feelium.projector.config import ProjectorConfig
from feelium.projector.renderer import Renderer
from feelium.lab.sim import protocol
from feelium.sim.sessions import session_presets
from feelium.sim.projection import FisheyeWarp, ProjectedLight, ProjectorOptics, SimPatternCapture, projected_hook
from feelium.sim.scene import HEIGHT, ROI, WIDTH, Session
from feelium.skin.face import FaceModel
from feelium.touch.config import TouchConfig
from feelium.lab.touch.evaluate import WIDEN_AFTER_S, WIDEN_BEFORE_S, TrialData, group_touches, score_trials
from feelium.touch.pipeline import TouchPipeline

CONDITIONS = ("flat", "face", "face_predicted")


class FaceVideo:
    """The talking avatar at the projector's frame rate, rendered once per projector frame index."""

    def __init__(self, renderer: Renderer, fps: float) -> None:
        self.renderer = renderer
        self.fps = fps
        self._cache: dict[int, np.ndarray] = {}

    def frame_index(self, t: float) -> int:
        return int(np.floor(t * self.fps + 1e-9))

    def at(self, t: float) -> np.ndarray:
        k = self.frame_index(t)
        if k not in self._cache:
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[k] = self.renderer.render(k / self.fps, None, [], talking=True)
        return self._cache[k]


def sim_calibration(
    seed: int, projector: ProjectorConfig, warp: FisheyeWarp, optics: ProjectorOptics, face: FaceModel | None = None
) -> tuple[ProjectorMap, dict]:
    """The Gray-code calibration run against the simulator, as a user would run it (not the true warp).

    ``face``: decoded on the whole face's frame over its box (``warp`` must be that frame's), so the map covers
    the whole face and not only the paper's rectangle."""
    size = (WIDTH, HEIGHT) if face is None else (face.width, face.height)
    light = ProjectedLight(warp, size, optics)
    capture = SimPatternCapture(Session("face-video-calibration"), light, np.random.default_rng([seed, 0xCA1]), face=face)
    result = run_calibration(capture, projector.calibration, (projector.width, projector.height), source="sim")
    return result.calibration, result.summary


def false_touches(trial: TrialData) -> int:
    """Emitted touches that overlap no labelled contact widened by the spec's margins (all of them in a negative trial)."""
    windows = [(c.t_on - WIDEN_BEFORE_S, c.t_off + WIDEN_AFTER_S) for c in trial.labels.contacts]
    return sum(
        1 for touch in group_touches(trial.events) if not any(touch.t_on <= w1 and touch.t_off >= w0 for w0, w1 in windows)
    )


@dataclass(frozen=True)
class _Setup:
    seed: int
    projector: ProjectorConfig
    touch: TouchConfig


class _Experiment:
    """Everything one worker needs: the calibration, the face video, the projection and the predictor."""

    def __init__(self, setup: _Setup) -> None:
        self.setup = setup
        warp = FisheyeWarp()
        optics = ProjectorOptics(flat_level=setup.projector.flat_level)
        self.calibration, self.calibration_summary = sim_calibration(setup.seed, setup.projector, warp, optics)
        self.video = FaceVideo(Renderer(setup.projector, self.calibration), setup.projector.fps)
        self.light = ProjectedLight(warp, (WIDTH, HEIGHT), optics)
        self.predictor = BacklightPredictor(setup.projector, self.calibration, (WIDTH, HEIGHT))

    def trial(self, item: protocol.Item) -> dict[str, TrialData]:
        """One protocol trial under the three conditions, with the same hands, noise and timing."""
        seed = self.setup.seed
        script = protocol.build_script(item, seed)
        session = session_presets(seed)[item.session]
        labels = script.labels()
        flat = protocol.render_frames(script, session, protocol.recording_rng(seed, item.name, 1))
        hook = projected_hook(self.light, self.video.at)
        face = list(protocol.render_frames(script, session, protocol.recording_rng(seed, item.name, 1), projected=hook))
        runs = {
            "flat": self._replay(flat, None),
            "face": self._replay(iter(face), None),
            "face_predicted": self._replay(iter(face), lambda t: self.predictor.gain(self.video.at(t))),
        }
        return {
            name: TrialData(item.name, labels, events, activity, max_area) for name, (events, activity, max_area) in runs.items()
        }

    def _replay(
        self, frames: Iterable[tuple[float, np.ndarray]], gain_at: Callable[[float], np.ndarray] | None
    ) -> tuple[list[TouchEvent], bool, float]:
        pipeline = TouchPipeline(self.setup.touch, (WIDTH, HEIGHT), ROI)
        events: list[TouchEvent] = []
        activity, max_area = False, 0.0
        for t, frame in frames:
            result = pipeline.process(t, frame, backlight_gain=None if gain_at is None else gain_at(t))
            events.extend(result.events)
            activity |= result.activity
            max_area = max(max_area, float(result.area))
        events.extend(pipeline.finish())
        return events, activity, max_area


_WORKER: _Experiment | None = None


def _init_worker(setup: _Setup) -> None:
    global _WORKER
    cv2.setNumThreads(1)  # the workers already use every core
    _WORKER = _Experiment(setup)


def _worker_trial(item: protocol.Item) -> dict[str, TrialData]:
    assert _WORKER is not None
    return _WORKER.trial(item)


def _summary(trials: list[TrialData]) -> dict[str, Any]:
    scored = score_trials(trials)["trials"]
    return {
        "recall": scored["recall"],
        "precision": scored["precision"],
        "tp": scored["tp"],
        "fn": scored["fn"],
        "fp": scored["fp"],
        "tn": scored["tn"],
        "false_touches": sum(false_touches(t) for t in trials),
        "touches": sum(len(group_touches(t.events)) for t in trials),
        "by_label": scored["by_label"],
    }


def run_experiment(
    *,
    scale: float = 0.1,
    seed: int = 1,
    projector: ProjectorConfig = ProjectorConfig(),
    touch: TouchConfig = TouchConfig(),
    labels: tuple[str, ...] | None = None,
    jobs: int = 1,
    progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, Any]:
    """Score the three conditions over the protocol's trials at ``scale`` (the continuous clips are left out)."""
    setup = _Setup(seed, projector, touch)
    items = [i for i in protocol.plan(scale) if not i.clip and (labels is None or i.label in labels)]
    local = _Experiment(setup)  # also gives the calibration summary; workers redo the same seeded calibration
    results: Iterator[dict[str, TrialData]]
    per_condition: dict[str, list[TrialData]] = {name: [] for name in CONDITIONS}

    def collect(stream: Iterator[dict[str, TrialData]]) -> None:
        for n, (item, runs) in enumerate(zip(items, stream), start=1):
            for name in CONDITIONS:
                per_condition[name].append(runs[name])
            if progress is not None:
                progress(n, len(items), item.name)

    if jobs <= 1:
        collect(map(local.trial, items))
    else:
        # Spawned, not forked (a fork of a threaded process can inherit a held lock), as the simulator does.
        spawn = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker, initargs=(setup,), mp_context=spawn) as pool:
            results = pool.map(_worker_trial, items)
            collect(results)
    conditions = {name: _summary(trials) for name, trials in per_condition.items()}
    flat, pred = conditions["flat"], conditions["face_predicted"]
    points = None
    if flat["recall"] is not None and pred["recall"] is not None:
        points = round(100.0 * (pred["recall"] - flat["recall"]), 2)
    return {
        "scale": scale,
        "seed": seed,
        "trials": len(items),
        "calibration": {
            "coverage": local.calibration_summary["coverage"],
            "fit_residual_px": local.calibration_summary["fit_residual_px"],
            "black_level": local.calibration_summary.get("black_level"),
            "gamma": local.calibration_summary.get("gamma"),
        },
        "conditions": conditions,
        "verdict": {
            "fp_trials_not_above_flat": pred["fp"] <= flat["fp"],
            "false_touches_not_above_flat": pred["false_touches"] <= flat["false_touches"],
            "recall_points_vs_flat": points,
            "recall_within_2_points": points is not None and points >= -2.0,
        },
    }


def format_table(report: dict[str, Any]) -> str:
    """The comparison as a plain-text table."""
    lines = [
        f"face-video robustness: {report['trials']} trials (scale {report['scale']}, seed {report['seed']}), "
        f"calibration coverage {report['calibration']['coverage'] * 100:.1f} %",
        f"{'condition':<16}{'recall':>8}{'precision':>11}{'tp':>5}{'fn':>5}{'fp trials':>11}{'tn':>5}{'false touches':>15}{'touches':>9}",
    ]

    def pct(v: float | None) -> str:
        return "-" if v is None else f"{v * 100:.1f}%"

    for name, c in report["conditions"].items():
        lines.append(
            f"{name:<16}{pct(c['recall']):>8}{pct(c['precision']):>11}{c['tp']:>5}{c['fn']:>5}{c['fp']:>11}{c['tn']:>5}"
            f"{c['false_touches']:>15}{c['touches']:>9}"
        )
    v = report["verdict"]
    lines.append(
        f"face_predicted vs flat: fp trials not above flat: {'yes' if v['fp_trials_not_above_flat'] else 'NO'}; "
        f"false touches not above flat: {'yes' if v['false_touches_not_above_flat'] else 'NO'}; "
        f"recall {v['recall_points_vs_flat']:+.2f} points ({'within' if v['recall_within_2_points'] else 'NOT within'} 2)"
        if v["recall_points_vs_flat"] is not None
        else "recall not measurable (no touch trials)"
    )
    return "\n".join(lines)
