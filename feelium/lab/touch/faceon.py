"""Touch with the face on the skin: the paper's protocol under a moving projected face (issue 17, point 1).

Every protocol trial (taps, holds, swipes, hovers, disturbances, empty scenes;
the continuous clips are left out) is rendered twice with the same hands,
session and camera noise: once under the flat back-light (``static``) and once
with a scripted wearer's video at full brightness (talking avatar, head sway,
scene cuts, fades to black and back) shown the way the daemon shows it: through
the projector's renderer, whose sensing floor keeps the skin lit
(``[projector] sensing_floor``), so a fade to black in the wearer's video is a
fade to the floor on the skin. The face run is replayed three ways:

- ``face_divided``: what the daemon did before: the frame on screen at the
  camera's timestamp, predicted through the Gray-code calibration, divided out;
- ``face_compensated``: the frames lit during the exposure (the daemon's
  latency estimate) with the prediction's spread over the latency uncertainty
  (:func:`feelium.touch.settle.predicted_exposure`), compensated through the
  per-pixel response learned online (:mod:`feelium.touch.photometric`), every
  shadow taken at the smallest depth the spread allows (:mod:`feelium.touch.settle`);
- ``face_no_spread``: the same with the spread left out, to measure the rule.

The world is physical and its parameters are stated here, chosen from the
hardware and never from detector scores: projected light scales only the
projector's share of the membrane's light (room light through the membrane does
not follow the face, ``projected_share_only``); the projector runs at 30 fps
with :data:`TRUE_LATENCY_S` behind its frame clock while the daemon assumes
``[touch] projector_latency_s``; the camera integrates over its exposure window, so a
cut straddles frames. Before each trial the pipeline has watched
:data:`WARMUP_S` of the same face without hands (a blimp shows the face all the
time; every condition gets the same warm-up).

Margins (issue 17, point 5): per condition and gate (instant and sustained),
the hardest negative's and the hardest positive's score against the gate's
threshold (:mod:`feelium.lab.touch.margins`); a negative margin on the negative
side means a hover at least that close passes the gate.
"""

from __future__ import annotations

import copy
import math
import multiprocessing
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from feelium.events import TouchEvent
from feelium.lab.projector.facevideo import sim_calibration
from feelium.lab.report import finish_experiment, print_progress
from feelium.lab.sim import protocol
from feelium.lab.touch.evaluate import WIDEN_AFTER_S, WIDEN_BEFORE_S, TrialData, score_trials
from feelium.lab.touch.margins import GateSeries, GateThresholds, margins
from feelium.projector.canvaslight import CanvasLightPredictor
from feelium.projector.config import ProjectorConfig
from feelium.projector.renderer import Renderer
from feelium.sim.camera import frame_times
from feelium.sim.projection import FisheyeWarp, ProjectedLight, ProjectorOptics, timed_hook
from feelium.sim.room import RoomLight
from feelium.sim.scene import HEIGHT, ROI, WIDTH, SceneRenderer, SceneState, Session, exposure_samples
from feelium.sim.sessions import session_presets
from feelium.skin.face import FaceModel
from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline
from feelium.touch.settle import predicted_exposure

CONDITIONS = ("static", "face_divided", "face_compensated", "face_no_spread")
TRUE_LATENCY_S = 0.040  # projector: frame clock to light on the membrane (the simulated world)
# The daemon assumes [touch] projector_latency_s (33 ms, one projector frame: 7 ms off on purpose) within
# projector_latency_sigma_s, and mixes over [touch] camera_exposure_s (30 ms, the simulated sensor's).
WARMUP_S = 5.0  # hand-free face seen before each trial
# The room's own light (:mod:`feelium.sim.room`): None is the paper's dim room; a RoomLight puts the face in a lit
# room (the lamp does not follow the face; the camera's auto-exposure follows the lamp).
ROOM: RoomLight | None = None


@dataclass(frozen=True)
class FaceScript:
    """The face video: talking avatar, head sway, scene cuts, fades to black and back (stated, not fitted)."""

    fps: float = 30.0
    cut_every_s: float = 2.5  # a new scene (framing) every this long
    fade_every_s: float = 7.0  # one fade to black and back per this long ...
    fade_at_s: float = 4.0  # ... starting this far into the period
    fade_s: float = 0.4  # fade down, and fade up again, each this long
    black_s: float = 0.3  # black between them
    sway_px: tuple[float, float] = (24.0, 16.0)  # head motion amplitude in canvas px (x, y)
    sway_hz: tuple[float, float] = (0.3, 0.45)
    # The light sweep (:mod:`feelium.lab.touch.dimlight`): when set, the video instead fades to black (over
    # ``fade_s``) by this trial time and stays black, so the whole trial is lit by the sensing floor alone.
    black_from_s: float | None = None

    def brightness(self, ts: float, trial_t: float = 0.0) -> float:
        """Fade factor (0 = black) at script time ``ts`` (trial time ``trial_t``)."""
        if self.black_from_s is not None:
            return min(max((self.black_from_s - trial_t) / self.fade_s, 0.0), 1.0)
        p = ts % self.fade_every_s - self.fade_at_s
        if p < 0.0 or p >= 2 * self.fade_s + self.black_s:
            return 1.0
        if p < self.fade_s:
            return 1.0 - p / self.fade_s
        if p < self.fade_s + self.black_s:
            return 0.0
        return (p - self.fade_s - self.black_s) / self.fade_s


class FaceVideo:
    """Projector frame ``k`` of the scripted wearer's video, starting ``offset_s`` into the script.

    The wearer's video (the talking avatar reframed, cut and faded: ``source`` is a renderer without a
    sensing floor, used only for its canvas) is shown through the daemon's ``renderer``, sensing floor
    included, exactly as the projector service shows a wearer's face.
    """

    def __init__(self, renderer: Renderer, source: Renderer, script: FaceScript, offset_s: float) -> None:
        self.renderer = renderer
        self.source = source
        self.script = script
        self.offset_s = offset_s

    def frame(self, k: int) -> np.ndarray:
        return self.shown(k)[0]

    def shown(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Projector frame ``k`` and its grey skin canvas (what the daemon predicts the light from)."""
        s = self.script
        ts = k / s.fps + self.offset_s
        return self.renderer.render_with_canvas(ts, self.wearer(ts), [])

    def wearer(self, ts: float) -> np.ndarray:
        """The wearer's video frame (canvas size, BGR) at script time ``ts``."""
        s = self.script
        image = self.source.canvas(ts, None, [], talking=True)
        h, w = image.shape[:2]
        scene = int(math.floor(ts / s.cut_every_s)) % 3
        zoom = (1.0, 1.3, 0.85)[scene]
        dx = s.sway_px[0] * math.sin(2 * math.pi * s.sway_hz[0] * ts) + (0.0, -60.0, 80.0)[scene]
        dy = s.sway_px[1] * math.sin(2 * math.pi * s.sway_hz[1] * ts + 1.0)
        m = cv2.getRotationMatrix2D((w / 2, h / 2), 0.0, zoom)
        m[:, 2] += (dx, dy)
        image = cv2.warpAffine(image, m, (w, h), borderMode=cv2.BORDER_REPLICATE)
        if scene == 2:
            image = image[:, ::-1].copy()
        fade = s.brightness(ts, ts - self.offset_s)
        if fade < 1.0:
            image = (image.astype(np.float32) * fade).astype(np.uint8)
        return image


class _Cache:
    """Per projector frame index, something costly (frames, factors, predictions); a small window kept."""

    def __init__(self, make: Callable[[int], Any]) -> None:
        self.make = make
        self._items: dict[int, Any] = {}

    def __call__(self, k: int) -> Any:
        if k not in self._items:
            if len(self._items) > 8:
                self._items.pop(min(self._items))
            self._items[k] = self.make(k)
        return self._items[k]


@dataclass
class TrialRun:
    data: TrialData  # with the per-frame gate series of the trial (warm-up left out)
    uncertain_frames: int


@dataclass(frozen=True)
class _Setup:
    seed: int
    projector: ProjectorConfig
    touch: TouchConfig
    script: FaceScript
    conditions: tuple[str, ...] = CONDITIONS
    # The whole curved front face (its frame, e.g. 1280x960) instead of the paper's 640x480 patch: the same
    # optics seen at the face's resolution (:meth:`FisheyeWarp.scaled`), the calibration decoded over the face's
    # box, and the renderer drawing the canvas over the face's u, v as the daemon does with a face model.
    face: FaceModel | None = None


class _Experiment:
    def __init__(self, setup: _Setup) -> None:
        self.setup = setup
        face = setup.face
        size = (WIDTH, HEIGHT) if face is None else (face.width, face.height)
        warp = FisheyeWarp().scaled(size[0] / WIDTH)
        optics = ProjectorOptics(flat_level=setup.projector.flat_level)
        self.calibration, _ = sim_calibration(setup.seed, setup.projector, warp, optics, face)
        self.renderer = Renderer(setup.projector, self.calibration, face)
        self.source = Renderer(replace(setup.projector, sensing_floor=0.0, fade_floor=0.0), self.calibration, face)
        self.light = ProjectedLight(warp, size, optics)
        self.predictor = CanvasLightPredictor(setup.projector, self.calibration, size, face)

    def trial(self, item: protocol.Item) -> dict[str, TrialRun]:
        seed, fps = self.setup.seed, self.setup.script.fps
        script = protocol.build_script(item, seed)
        session = session_presets(seed)[item.session]
        offset = float(protocol.recording_rng(seed, item.name, 7).uniform(0.0, self.setup.script.fade_every_s))
        video = FaceVideo(self.renderer, self.source, self.setup.script, offset)
        shown = _Cache(video.shown)
        exposure = session.sensor.exposure_s
        hook = timed_hook(self.light, lambda k: shown(k)[0], fps, TRUE_LATENCY_S, exposure)
        gains = _Cache(lambda k: self.predictor.gain(shown(k)[1]))

        def divided(t: float) -> dict[str, np.ndarray]:
            return {"backlight_gain": gains(int(math.floor(t * fps + 1e-9)))}

        cfg = self.setup.touch

        def compensated(t: float) -> dict[str, np.ndarray]:
            reach = cfg.projector_latency_s + cfg.projector_latency_sigma_s + cfg.camera_exposure_s / 2.0
            first, last = math.floor((t - reach) * fps), math.floor(t * fps) + 1
            light, spread = predicted_exposure(
                [(k / fps, k) for k in range(first, last + 1)],
                gains,
                t,
                exposure_s=cfg.camera_exposure_s,
                latency_s=cfg.projector_latency_s,
                latency_sigma_s=cfg.projector_latency_sigma_s,
            )
            return {"projected_light": light, "projected_spread": spread}

        def no_spread(t: float) -> dict[str, np.ndarray]:
            return {"projected_light": compensated(t)["projected_light"]}
        wanted = self.setup.conditions
        static = self._render(script, session, item, None) if "static" in wanted else []
        face = self._render(script, session, item, hook) if set(wanted) - {"static"} else []
        feeds: dict[str, tuple[list[tuple[float, np.ndarray]], Callable[[float], dict[str, np.ndarray]]]] = {
            "static": (static, lambda t: {}),
            "face_divided": (face, divided),
            "face_compensated": (face, compensated),
            "face_no_spread": (face, no_spread),
        }
        return {name: self._replay(feeds[name][0], script, item, cfg, feeds[name][1]) for name in wanted}

    def _render(self, script: Any, session: Session, item: protocol.Item, hook: Any) -> list[tuple[float, np.ndarray]]:
        """Warm-up (hand-free) frames before 0, then the trial's frames, as the camera captures them."""
        rng = protocol.recording_rng(self.setup.seed, item.name, 1)
        scene = SceneRenderer(
            session, rng, width=WIDTH, height=HEIGHT, roi=ROI, projected=hook, projected_share_only=True, room_light=ROOM
        )
        warmup = np.arange(-WARMUP_S, -0.25, 1.0 / session.sensor.fps)
        out = [(float(t), scene.frame(float(t), SceneState())) for t in warmup]
        for t in frame_times(session.sensor, script.duration, rng):
            out.append((float(t), scene.frame(float(t), exposure_samples(script.state, float(t), session.sensor.exposure_s))))
        return out

    def _replay(
        self,
        frames: list[tuple[float, np.ndarray]],
        script: Any,
        item: protocol.Item,
        config: TouchConfig,
        inputs: Callable[[float], dict[str, np.ndarray]],
    ) -> TrialRun:
        pipeline = TouchPipeline(config, (WIDTH, HEIGHT), ROI)
        labels = script.labels()
        events: list[TouchEvent] = []
        activity, max_area = False, 0.0
        rows: list[tuple[float, float, float, float]] = []
        for t, frame in frames:
            result = pipeline.process(t, frame, **inputs(t))
            if t < 0.0:
                continue  # warm-up: nothing in the scene, nothing scored
            events.extend(result.events)
            activity |= result.activity
            max_area = max(max_area, float(result.area))
            rows.append((t, result.anchor, result.core_depth, result.edge))
        events.extend(pipeline.finish())
        t, anchor, core, edge = (np.asarray(c, float) for c in zip(*rows)) if rows else (np.zeros(0),) * 4
        series = GateSeries(t, anchor, core, edge, labels.contacts, not labels.contacts)
        data = TrialData(item.name, labels, events, activity, max_area, series)
        return TrialRun(data, pipeline.uncertain_frames)


_WORKER: _Experiment | None = None


def _init_worker(setup: _Setup) -> None:
    global _WORKER
    cv2.setNumThreads(1)
    _WORKER = _Experiment(setup)


def _worker_trial(item: protocol.Item) -> dict[str, TrialRun]:
    assert _WORKER is not None
    return _WORKER.trial(item)


def summarise(runs: list[TrialRun], touch: TouchConfig) -> dict[str, Any]:
    scored = score_trials([r.data for r in runs])
    gates = GateThresholds(touch.contact_edge, touch.instant_depth, touch.anchor_threshold, touch.anchor_min_age_s)
    series = [r.data.series for r in runs if r.data.series is not None]
    trials = scored["trials"]
    return {
        "recall": trials["recall"],
        "precision": trials["precision"],
        "tp": trials["tp"],
        "fn": trials["fn"],
        "negatives_fired": trials["fp"],
        "negatives": trials["fp"] + trials["tn"],
        "localisation_error_px": scored["localisation"]["error_px"],
        "uncertain_frames": sum(r.uncertain_frames for r in runs),
        "margins": margins(series, gates, widen=(WIDEN_BEFORE_S, WIDEN_AFTER_S)),
        "by_label": trials["by_label"],
    }


def run_experiment(
    *,
    scale: float = 0.3,
    seed: int = 1,
    projector: ProjectorConfig = ProjectorConfig(),
    touch: TouchConfig = TouchConfig(),
    script: FaceScript = FaceScript(),
    labels: tuple[str, ...] | None = None,
    conditions: tuple[str, ...] = CONDITIONS,
    jobs: int = 1,
    progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, Any]:
    """Score every condition over the protocol's trials at ``scale``."""
    setup = _Setup(seed, projector, touch, script, conditions)
    items = [i for i in protocol.plan(scale) if not i.clip and (labels is None or i.label in labels)]
    per: dict[str, list[TrialRun]] = {name: [] for name in conditions}

    def collect(stream: Iterator[dict[str, TrialRun]]) -> None:
        for n, (item, runs) in enumerate(zip(items, stream), start=1):
            for name in conditions:
                per[name].append(runs[name])
            if progress is not None:
                progress(n, len(items), item.name)

    if jobs <= 1:
        collect(map(_Experiment(setup).trial, items))
    else:
        spawn = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker, initargs=(setup,), mp_context=spawn) as pool:
            collect(pool.map(_worker_trial, items))
    return {
        "scale": scale,
        "seed": seed,
        "trials": len(items),
        "latency_s": {"true": TRUE_LATENCY_S, "assumed": touch.projector_latency_s, "sigma": touch.projector_latency_sigma_s},
        "warmup_s": WARMUP_S,
        "conditions": {name: summarise(runs, touch) for name, runs in per.items()},
    }


def format_table(report: dict[str, Any]) -> str:
    lines = [
        f"face on the skin: {report['trials']} trials (scale {report['scale']}, seed {report['seed']})",
        f"{'condition':<18}{'recall':>8}{'neg fired':>11}{'loc med px':>12}{'uncertain':>11}"
        f"{'gate':>11}{'hardest neg':>13}{'margin':>8}{'hardest pos':>13}{'margin':>8}",
    ]

    def num(v: float | None, fmt: str = ".3f") -> str:
        return "-" if v is None else format(v, fmt)

    for name, c in report["conditions"].items():
        loc = c["localisation_error_px"]
        for k, (gate, m) in enumerate(c["margins"].items()):
            head = (
                f"{name:<18}{num(c['recall']):>8}{c['negatives_fired']:>6} / {c['negatives']:<3}"
                f"{num(loc['median'] if loc else None, '.2f'):>12}{c['uncertain_frames']:>11}"
                if k == 0
                else " " * 61
            )
            lines.append(
                f"{head}{gate:>11}{num(m['hardest_negative']):>13}{num(m['negative_margin'], '+.3f'):>8}"
                f"{num(m['hardest_positive']):>13}{num(m['positive_margin'], '+.3f'):>8}"
            )
    return "\n".join(lines)


def frame_cost(*, seed: int = 1, timed: int = 60, repeats: int = 4, touch: TouchConfig = TouchConfig()) -> dict[str, Any]:
    """CPU time per camera frame (one OpenCV thread, the calling thread's time) of what the face adds.

    One hold trial is rendered under the flat back-light and under the face; the last ``timed`` camera frames
    of each replay are timed, ``repeats`` times, after the same warm-up. ``exposure_light`` is the daemon's
    side of the prediction per camera frame at the daemon's working size (``[touch] width x height``): each
    new projector frame predicted once from its skin canvas
    (:class:`feelium.projector.canvaslight.CanvasLightPredictor`), the
    exposure mix and its spread (:class:`feelium.touch.projected.ExposureLight`). Medians and p95 in ms.
    """
    import time

    from feelium.touch.projected import ExposureLight

    cv2.setNumThreads(1)
    setup = _Setup(seed, ProjectorConfig(), touch, FaceScript())
    ex = _Experiment(setup)
    item = next(i for i in protocol.plan(0.1) if i.label == "hold")
    script = protocol.build_script(item, seed)
    session = session_presets(seed)[item.session]
    video = FaceVideo(ex.renderer, ex.source, setup.script, 0.0)
    shown = _Cache(video.shown)
    fps = setup.script.fps
    hook = timed_hook(ex.light, lambda k: shown(k)[0], fps, TRUE_LATENCY_S, session.sensor.exposure_s)
    gains = _Cache(lambda k: ex.predictor.gain(shown(k)[1]))
    static = ex._render(script, session, item, None)
    face = ex._render(script, session, item, hook)
    daemon_size = (touch.width, touch.height)
    predictor = CanvasLightPredictor(setup.projector, ex.calibration, daemon_size)

    def inputs(t: float, spread: bool) -> dict[str, np.ndarray]:
        reach = touch.projector_latency_s + touch.projector_latency_sigma_s + touch.camera_exposure_s / 2.0
        ks = range(math.floor((t - reach) * fps), math.floor(t * fps) + 2)
        light, sp = predicted_exposure(
            [(k / fps, k) for k in ks], gains, t, exposure_s=touch.camera_exposure_s,
            latency_s=touch.projector_latency_s, latency_sigma_s=touch.projector_latency_sigma_s,
        )  # fmt: skip
        return {"projected_light": light, "projected_spread": sp} if spread else {"projected_light": light}

    variants: dict[str, tuple[list[tuple[float, np.ndarray]], Callable[[float], dict[str, np.ndarray]]]] = {
        "static": (static, lambda t: {}),
        "face_no_spread": (face, lambda t: inputs(t, False)),
        "face_compensated": (face, lambda t: inputs(t, True)),
    }
    out: dict[str, Any] = {}
    for name, (clip, feed) in variants.items():
        fed = [(t, f, feed(t)) for t, f in clip]  # prepared outside the timing
        samples: list[float] = []
        for _ in range(repeats):
            pipeline = TouchPipeline(touch, (WIDTH, HEIGHT), ROI)
            for n, (t, f, kw) in enumerate(fed):
                start = time.thread_time()
                pipeline.process(t, f, **kw)
                if n >= len(fed) - timed:
                    samples.append(time.thread_time() - start)
        out[name] = _ms(samples)
    samples = []
    for _ in range(repeats):
        light = ExposureLight(predictor.gain, touch)
        for t, _f in face[-timed:]:
            k = math.floor(t * fps)
            history = [(j / fps, j, shown(j)[1]) for j in range(k - 4, k + 2)]
            start = time.thread_time()
            light(history, t)
            samples.append(time.thread_time() - start)
    out["exposure_light"] = _ms(samples)
    out["timed_frames"], out["repeats"], out["daemon_size"] = timed, repeats, list(daemon_size)
    return out


def _ms(samples: list[float]) -> dict[str, float]:
    a = np.asarray(samples) * 1000.0
    return {"median": round(float(np.median(a)), 3), "p95": round(float(np.percentile(a, 95)), 3)}


def main(argv: list[str] | None = None) -> int:
    """``python -m feelium.lab.touch.faceon [--scale S] [--jobs N] [--json FILE]``: the table, and the report."""
    import argparse
    import json

    parser = argparse.ArgumentParser(prog="python -m feelium.lab.touch.faceon", description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=0.3, help="share of the paper's 228 trials (default 0.3)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--cost", action="store_true", help="only the CPU time per frame of the face's compensation")
    args = parser.parse_args(argv)
    if args.cost:
        print(json.dumps(frame_cost(seed=args.seed), indent=1))
        return 0
    report = run_experiment(
        scale=args.scale,
        seed=args.seed,
        jobs=args.jobs,
        progress=print_progress,
    )
    return finish_experiment(format_table(report), report, args.json)


if __name__ == "__main__":
    raise SystemExit(main())
