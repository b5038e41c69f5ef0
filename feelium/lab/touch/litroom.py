"""Touch in a lit room: the paper's protocol under room light, switches, daylight and a passer-by (issue 17, point 2).

Every protocol trial (the continuous clips are left out) is rendered under each
condition with the same hands, session and camera noise, after
:data:`WARMUP_S` of the same room without hands, and replayed through the touch
pipeline. The room's light is :mod:`feelium.sim.room`'s model; its parameters
are stated here, from rooms and lamps, never from detector scores:

- ``dim``: the paper's room (no light of the room's own): the baseline;
- ``lit``: a lit living room, room light through the membrane as bright as the
  projector's (:data:`LIT`, level 1.0 of the ROI's mean back-light);
- ``switch-on`` / ``switch-off``: the lamp switched on (ramp :data:`ON_RAMP_S`,
  a warm LED or halogen bulb) or off (:data:`OFF_RAMP_S`), at a drawn time; in
  touch trials between :data:`SWITCH_BEFORE_S` before the first contact, so
  recall there measures sensitivity within about a second of a switch;
- ``drift``: daylight at :data:`DRIFT_LEVEL` varying +-:data:`DRIFT_AMP` over
  :data:`DRIFT_PERIOD_S` (clouds: up to 9 % of the back-light per second);
- ``passer-by``: the lit room while a person walks between the lamp and the
  blimp (:class:`feelium.sim.room.Passer`) at a drawn time in the trial;
- ``too-bright``: daylight at :data:`TOO_BRIGHT_LEVEL` with the camera's exposure
  at its floor (:data:`TOO_BRIGHT_AE_FLOOR`): a saturated membrane, where the
  touch service must say so in health rather than go silent unannounced.

Per condition: trial recall, negatives fired, false touches (touches outside
every widened contact, in any trial), localisation error median; for the
switches, recovery time: a hand-free twin of each trial (same light, same
noise stream, no hands) is replayed too, and recovery is the time from the
switch's start until the hand-free membrane's relative depth (99th percentile
over the ROI of its absolute value, smoothed as the pipeline does) stays
within ``candidate_depth``: no false shadow deep enough to be a candidate, and
no true shadow's depth off by that much, anywhere (steady light keeps it at
0.05-0.08, the noise, in bright sessions; in the dimmest sessions steady dim light
alone reaches 0.15, so there it reads the camera's noise, not the switch).

*Sensitivity* after a switch (:func:`sensitivity_recovery`) measures what the
recovery is for: how deep a known contact reads. At every frame of the
hand-free twin from the switch on, a copy of the pipeline is handed that frame
with a fingertip's shadow of known depth (:data:`SENSE_DEPTH`, a disc of
:data:`SENSE_RADIUS_PX`) pressed at each of :data:`SENSE_PLACES` in turn, and
reads its core depth; the same contacts are read on the twin of the room's
final light held steady (the steady condition's twin, same noise stream). Full
sensitivity is recovered from the first frame after which every place reads
within :data:`SENSE_TOLERANCE` of its steady reading (median over the steady
twin) and is found at all. The noise of the new light is in both readings, so
only what the switch left behind counts.
"""

from __future__ import annotations

import copy
import functools
import multiprocessing
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from feelium.events import TouchEvent
from feelium.lab.sim import protocol
from feelium.lab.touch.evaluate import (
    WIDEN_AFTER_S, WIDEN_BEFORE_S, TrialData, group_touches, score_margins, score_trials,
)  # fmt: skip
from feelium.lab.touch.margins import GateSeries, GateThresholds
from feelium.recording import NEGATIVE_LABELS
from feelium.skin import probe
from feelium.skin.probe import probe_light, probe_pattern
from feelium.sim.camera import frame_times
from feelium.sim.room import Passer, RoomLight
from feelium.sim.scene import HEIGHT, ROI, WIDTH, SceneRenderer, SceneState, exposure_samples
from feelium.sim.sessions import session_presets
from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline

if TYPE_CHECKING:
    from feelium.lab.touch import face_zones

CONDITIONS = ("dim", "lit", "switch-on", "switch-off", "drift", "passer-by", "too-bright")
SWITCHES = ("switch-on", "switch-off")
WARMUP_S = 3.0  # hand-free frames in the trial's starting light before it begins
LIT = 1.0  # a lit living room: room light through the membrane as bright as the projector's
ON_RAMP_S = 0.1
OFF_RAMP_S = 0.05
SWITCH_BEFORE_S = (0.5, 1.5)  # a touch trial's switch comes this long before its first contact
DRIFT_LEVEL, DRIFT_AMP, DRIFT_PERIOD_S = 0.6, 0.5, 20.0
# Too bright to see: daylight on the membrane, about ten times a lamp-lit room (a window's 1000-3000 lux against a
# living room's 100-300), so 8 times the projector's light (the highest level of docs/touch.md's *Too bright*
# table), with the camera's exposure at its floor, the dim room's (``RoomLight.ae_floor`` 1: the daemon locks the
# rear camera's exposure after settling, so the daylight that came after is not followed). The membrane then gets 9
# times its dim level, whose ROI mean is about half of the session's peak of 125-238 DN: every pixel of the ROI
# would read over 255. Not chosen from detector scores; what it must show is health saying "too bright".
TOO_BRIGHT_LEVEL = 8.0
TOO_BRIGHT_AE_FLOOR = 1.0
RECOVERY_PERCENTILE = 99.0
# The known contact of the sensitivity measure: the frustrated reflection's share of a pressed fingertip in the dim
# room (0.4-0.5, docs/touch.md, the sessions' contact_depth), over a fingertip's pad (12 camera px across at 640 x 480).
SENSE_DEPTH = 0.45
SENSE_RADIUS_PX = 6.0
SENSE_PLACES = ((0.5, 0.5), (0.2, 0.25), (0.8, 0.25), (0.2, 0.75), (0.8, 0.75))  # fractions of the ROI: centre, corners
# How far a known contact's depth may read from steady light's: a third of the thinnest instant-gate margin of a
# positive in the steady lit rooms (+0.144 to +0.171 over six seeds, docs/touch.md), so the gates decide as in steady light.
SENSE_TOLERANCE = 0.05
STEADY_EVERY = 5  # the steady twin's readings are taken on every 5th frame: a median over 15-20 frames of the trial
# The projector lays its faint probe over the static skin (feelium.projector.probe) and the pipeline is told its
# light, so it learns the projector's share per place (feelium.touch.roomshare). False: the static back-light.
PROBE = True
AMPLITUDE = probe.AMPLITUDE  # the probe's amplitude (the experiment of docs/projector.md, *The probe*, varies it)


def room_for(
    condition: str, item: protocol.Item | face_zones.Trial, seed: int, duration: float, first_contact: float | None
) -> RoomLight | None:
    """The room light of one trial under ``condition`` (times drawn from the trial's own RNG stream, keyed by its
    name: a protocol item or a whole-face trial)."""
    rng = protocol.recording_rng(seed, item.name, 11)
    angle = float(rng.uniform(0.0, 360.0))
    if condition == "dim":
        return None
    if condition == "lit":
        return RoomLight(level=LIT, gradient_angle_deg=angle)
    if condition in SWITCHES:
        if first_contact is not None:
            when = max(0.2, first_contact - float(rng.uniform(*SWITCH_BEFORE_S)))
        else:
            when = float(rng.uniform(0.2, 0.8)) * duration
        if condition == "switch-on":
            return RoomLight(level=0.0, steps=((when, LIT, ON_RAMP_S),), gradient_angle_deg=angle)
        return RoomLight(level=LIT, steps=((when, 0.0, OFF_RAMP_S),), gradient_angle_deg=angle)
    if condition == "drift":
        return RoomLight(
            level=DRIFT_LEVEL, drift_amp=DRIFT_AMP, drift_period_s=DRIFT_PERIOD_S,
            drift_phase=float(rng.uniform(0.0, 2 * np.pi)), gradient_angle_deg=angle,
        )  # fmt: skip
    if condition == "too-bright":
        return RoomLight(level=TOO_BRIGHT_LEVEL, gradient_angle_deg=angle, ae_floor=TOO_BRIGHT_AE_FLOOR)
    if condition == "passer-by":
        return RoomLight(level=LIT, gradient_angle_deg=angle, passer=Passer(t0=float(rng.uniform(0.1, 0.7)) * duration))
    raise ValueError(f"unknown condition {condition!r}; expected one of {', '.join(CONDITIONS)}")


@dataclass
class Run:
    data: TrialData
    false_touches: int
    recovery_s: float | None  # switch conditions only
    sensitivity_s: float | None = None  # switch conditions only: :func:`sensitivity_recovery`


def _false_touches(events: list[TouchEvent], data: TrialData) -> int:
    windows = [(c.t_on - WIDEN_BEFORE_S, c.t_off + WIDEN_AFTER_S) for c in data.labels.contacts]
    return sum(1 for t in group_touches(events) if not any(t.t_on <= w1 and t.t_off >= w0 for w0, w1 in windows))


def render(
    script: Any, session: Any, item: protocol.Item, seed: int, room: RoomLight | None, *, hands: bool = True,
    projected: Callable[[float], np.ndarray] | None = None,
) -> list[tuple[float, np.ndarray]]:
    """Warm-up (hand-free) frames before 0, then the trial's frames; the same noise stream for every condition.

    ``projected``: the projector's light factor at a camera time, instead of the ideal probe (a recording renders
    the probe through projector frames, :mod:`feelium.lab.sim.take_litroom`)."""
    rng = protocol.recording_rng(seed, item.name, 1)
    if projected is None and PROBE:
        pattern = probe_pattern(WIDTH, HEIGHT)
        projected = lambda t: probe_light(t, pattern, AMPLITUDE)  # noqa: E731
    # The probe's cells change the projector's direct light only: the room returns the skin's mean, which it keeps.
    scene = SceneRenderer(
        session, rng, width=WIDTH, height=HEIGHT, roi=ROI, room_light=room, projected=projected,
        projected_share_only=True,
    )  # fmt: skip
    warmup = np.arange(-WARMUP_S, -0.25, 1.0 / session.sensor.fps)
    out = [(float(t), scene.frame(float(t), SceneState())) for t in warmup]
    empty = SceneState()
    for t in frame_times(session.sensor, script.duration, rng):
        t = float(t)
        if hands:
            state = exposure_samples(script.state, t, session.sensor.exposure_s)
        else:
            state = SceneState(room=script.room(t), exposure=script.exposure(t)) if script.room_steps else empty
        out.append((t, scene.frame(t, state)))
    return out


def depth_error(pipeline: TouchPipeline, frame: np.ndarray) -> float | None:
    """How far the hand-free membrane is from the reference: percentile of |relative depth| (smoothed), or None."""
    ref = pipeline.reference.image
    if ref is None:
        return None
    work = pipeline.geometry.cut_roi(frame[ROI[1] : ROI[1] + ROI[3], ROI[0] : ROI[0] + ROI[2]])
    usable = ref >= pipeline.config.dark_reference_level
    ratio = np.where(usable, work / np.maximum(ref, 1e-3), 1.0).astype(np.float32)
    ratio /= np.float32(np.median(ratio[usable])) if usable.any() else np.float32(1.0)
    sigma = pipeline.geometry.px(pipeline.config.blur_sigma_px)
    smooth = cv2.GaussianBlur(1.0 - ratio, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
    return float(np.percentile(np.abs(smooth[usable]), RECOVERY_PERCENTILE))


def recovery(frames: list[tuple[float, np.ndarray]], config: TouchConfig, switch_at: float) -> float:
    """Seconds from ``switch_at`` until the hand-free twin's depth error stays within ``candidate_depth`` (inf: never)."""
    pipeline = TouchPipeline(config, (WIDTH, HEIGHT), ROI)
    pattern = probe_pattern(WIDTH, HEIGHT) if PROBE else None
    bad = []
    for t, frame in frames:
        err = depth_error(pipeline, frame)
        pipeline.process(t, frame, probe_light=_probe(t, pattern))
        bad.append((t, t >= switch_at and err is not None and err > config.candidate_depth))
    return recovered(bad, switch_at)


def recovered(bad: list[tuple[float, bool]], switch_at: float) -> float:
    """Seconds from ``switch_at`` to the first frame after the last bad one (0.0: none was bad; inf: bad to the end)."""
    last_bad = max((t for t, b in bad if b), default=None)
    if last_bad is None:
        return 0.0
    after = [t for t, _ in bad if t > last_bad]
    return after[0] - switch_at if after else float("inf")


def _pressed(frame: np.ndarray, place: tuple[float, float], roi: tuple[int, int, int, int] = ROI) -> np.ndarray:
    """``frame`` with a fingertip's shadow of :data:`SENSE_DEPTH` at ``place`` (fractions of ``roi``), its edge
    blurred by 1 px."""
    return np.clip(np.rint(frame * _fingertip(frame.shape[:2], tuple(place), tuple(roi))), 0, 255).astype(np.uint8)


@functools.lru_cache(maxsize=4 * len(SENSE_PLACES))
def _fingertip(shape: tuple[int, ...], place: tuple[float, float], roi: tuple[int, int, int, int]) -> np.ndarray:
    """The (H, W) float32 transmission of :func:`_pressed`'s fingertip (read-only), made once per place and frame
    size: every reading of every frame presses the same few places."""
    x0, y0, w, h = roi
    cx, cy = x0 + place[0] * w, y0 + place[1] * h
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float32)
    disc = cv2.GaussianBlur(((xs - cx) ** 2 + (ys - cy) ** 2 <= SENSE_RADIUS_PX**2).astype(np.float32), (0, 0), 1.0)
    transmission = 1.0 - SENSE_DEPTH * disc
    transmission.setflags(write=False)
    return transmission


def sensed(
    frames: Iterable[tuple[float, np.ndarray]],
    config: TouchConfig,
    since: float,
    every: int = 1,
    *,
    pipeline: TouchPipeline | None = None,
    light: Callable[[float], dict[str, Any]] | None = None,
    roi: tuple[int, int, int, int] = ROI,
) -> list[tuple[float, list[float]]]:
    """Per ``every``-th frame from ``since``: the core depth a copy of the pipeline reads for the known contact at each
    of :data:`SENSE_PLACES` pressed on that frame (0 where it finds no shadow); the pipeline itself sees every frame as
    it is.

    ``pipeline``, ``light`` (per frame time, the keyword arguments the pipeline is handed with the frame) and ``roi``
    default to the experiment's (its frame and ROI, the ideal probe); a recording's replay passes its own
    (:mod:`feelium.lab.touch.switch_recovery`), so both measure with this one function."""
    if pipeline is None:
        pipeline = TouchPipeline(config, (WIDTH, HEIGHT), ROI)
    if light is None:
        pattern = probe_pattern(WIDTH, HEIGHT) if PROBE else None
        light = lambda t: {"probe_light": _probe(t, pattern)}  # noqa: E731
    out = []
    for n, (t, frame) in enumerate(frames):
        extra = light(t)
        if t >= since and pipeline.reference.image is not None and n % every == 0:
            pressed = (copy.deepcopy(pipeline).process(t, _pressed(frame, p, roi), **extra) for p in SENSE_PLACES)
            out.append((t, [result.core_depth for result in pressed]))
        pipeline.process(t, frame, **extra)
    return out


def off_steady(depths: list[float], steady: np.ndarray) -> bool:
    """Whether a frame's readings of the known contact are not yet those of steady light: a place not found, or one
    reading more than :data:`SENSE_TOLERANCE` from ``steady`` (per place). The one definition of "not recovered"."""
    d = np.asarray(depths, float)
    return bool(np.any(d <= 0.0) or np.any(np.abs(d - steady) > SENSE_TOLERANCE))


def sensitivity_recovery(
    frames: Iterable[tuple[float, np.ndarray]],
    steady: Iterable[tuple[float, np.ndarray]],
    config: TouchConfig,
    switch_at: float,
    *,
    reader: Callable[[], dict[str, Any]] | None = None,
) -> float:
    """Seconds from ``switch_at`` until the known contact reads as in ``steady`` (the final light held) at every place,
    from then on (inf: never): see the module's docstring.

    ``reader()``: a new pipeline, its light and ROI for :func:`sensed` (one per reading: a pipeline and a light
    feed follow their own time), for frames that are not the experiment's (a recording's, in ``eval``)."""
    own = reader if reader is not None else dict
    reference = np.median(np.array([d for _, d in sensed(steady, config, 0.0, every=STEADY_EVERY, **own())]), axis=0)
    return recovered(
        [(t, off_steady(depths, reference)) for t, depths in sensed(frames, config, switch_at, **own())], switch_at
    )


def _probe(t: float, pattern: np.ndarray | None) -> np.ndarray | None:
    return None if pattern is None else probe_light(t, pattern, AMPLITUDE)


def replay(
    frames: list[tuple[float, np.ndarray]], config: TouchConfig
) -> tuple[list[TouchEvent], bool, float, dict[str, np.ndarray]]:
    """Events, activity, largest area and the per-frame gate scores (from 0 s) of one trial."""
    pipeline = TouchPipeline(config, (WIDTH, HEIGHT), ROI)
    pattern = probe_pattern(WIDTH, HEIGHT) if PROBE else None
    events: list[TouchEvent] = []
    activity, max_area = False, 0.0
    series: dict[str, list[float]] = {"t": [], "anchor": [], "core_depth": [], "edge": [], "projected": []}
    for t, frame in frames:
        result = pipeline.process(t, frame, probe_light=_probe(t, pattern))
        if t < 0.0:
            continue
        events.extend(result.events)
        activity |= result.activity
        max_area = max(max_area, float(result.area))
        for key, value in (("t", t), ("anchor", result.anchor), ("core_depth", result.core_depth), ("edge", result.edge)):
            series[key].append(value)
        series["projected"].append(np.nan if result.projected_depth is None else result.projected_depth)
    events.extend(pipeline.finish())
    return events, activity, max_area, {k: np.asarray(v, np.float64) for k, v in series.items()}


@dataclass(frozen=True)
class _Setup:
    seed: int
    touch: TouchConfig
    conditions: tuple[str, ...]


def trial(setup: _Setup, item: protocol.Item) -> dict[str, Run]:
    """Every condition of one protocol trial."""
    script = protocol.build_script(item, setup.seed)
    session = session_presets(setup.seed)[item.session]
    labels = script.labels()
    first = labels.contacts[0].t_on if labels.contacts else None
    runs = {}
    for condition in setup.conditions:
        room = room_for(condition, item, setup.seed, script.duration, first)
        frames = render(script, session, item, setup.seed, room)
        events, activity, max_area, s = replay(frames, setup.touch)
        series = GateSeries(
            s["t"], s["anchor"], s["core_depth"], s["edge"], labels.contacts, item.label in NEGATIVE_LABELS, s["projected"]
        )
        data = TrialData(item.name, labels, events, activity, max_area, series)
        rec = sens = None
        if condition in SWITCHES and room is not None:
            twin = render(script, session, item, setup.seed, room, hands=False)
            rec = recovery(twin, setup.touch, room.steps[0][0])
            held = room_for("dim" if condition == "switch-off" else "lit", item, setup.seed, script.duration, first)
            steady = render(script, session, item, setup.seed, held, hands=False)
            sens = sensitivity_recovery(twin, steady, setup.touch, room.steps[0][0])
        runs[condition] = Run(data, _false_touches(events, data), rec, sens)
    return runs


_SETUP: _Setup | None = None


def _init_worker(setup: _Setup) -> None:
    global _SETUP
    cv2.setNumThreads(1)
    _SETUP = setup


def _worker_trial(item: protocol.Item) -> dict[str, Run]:
    assert _SETUP is not None
    return trial(_SETUP, item)


def summarise(runs: list[Run], touch: TouchConfig = TouchConfig()) -> dict[str, Any]:
    scored = score_trials([r.data for r in runs])
    gates = GateThresholds(
        touch.contact_edge, touch.instant_depth, touch.anchor_threshold, touch.anchor_min_age_s,
        touch.contact_projected_depth,
    )
    margins = score_margins([r.data for r in runs], [], gates)["trials"] or {}
    trials = scored["trials"]
    recoveries = [r.recovery_s for r in runs if r.recovery_s is not None]
    sensitivities = [r.sensitivity_s for r in runs if r.sensitivity_s is not None]
    return {
        "recall": trials["recall"],
        "tp": trials["tp"],
        "fn": trials["fn"],
        "negatives_fired": trials["fp"],
        "negatives": trials["fp"] + trials["tn"],
        "false_touches": sum(r.false_touches for r in runs),
        "localisation_error_px": scored["localisation"]["error_px"],
        "recovery_s": None
        if not recoveries
        else {"median": float(np.median(recoveries)), "max": float(max(recoveries)), "n": len(recoveries)},
        "sensitivity_s": None
        if not sensitivities
        else {"median": float(np.median(sensitivities)), "max": float(max(sensitivities)), "n": len(sensitivities)},
        "by_label": trials["by_label"],
        "margins": {
            gate: {"negative": m["negative_margin"], "positive": m["positive_margin"]} for gate, m in margins.items()
        },
    }


def run_experiment(
    *,
    scale: float = 0.2,
    seed: int = 1,
    touch: TouchConfig = TouchConfig(),
    conditions: tuple[str, ...] = CONDITIONS,
    labels: tuple[str, ...] | None = None,
    jobs: int = 1,
    progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, Any]:
    """Score every condition over the protocol's trials at ``scale``."""
    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown:
        raise ValueError(f"unknown condition {unknown[0]!r}; expected some of {', '.join(CONDITIONS)}")
    setup = _Setup(seed, touch, tuple(conditions))
    items = [i for i in protocol.plan(scale) if not i.clip and (labels is None or i.label in labels)]
    per: dict[str, list[Run]] = {name: [] for name in setup.conditions}

    def collect(stream: Iterator[dict[str, Run]]) -> None:
        for n, (item, runs) in enumerate(zip(items, stream), start=1):
            for name in setup.conditions:
                per[name].append(runs[name])
            if progress is not None:
                progress(n, len(items), item.name)

    if jobs <= 1:
        collect(trial(setup, item) for item in items)
    else:
        spawn = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker, initargs=(setup,), mp_context=spawn) as pool:
            collect(pool.map(_worker_trial, items))
    return {
        "scale": scale,
        "seed": seed,
        "trials": len(items),
        "warmup_s": WARMUP_S,
        "lit_level": LIT,
        "conditions": {name: summarise(runs, touch) for name, runs in per.items()},
    }


def format_table(report: dict[str, Any]) -> str:
    lines = [
        f"lit room: {report['trials']} trials (scale {report['scale']}, seed {report['seed']})",
        f"{'condition':<12}{'recall':>8}{'neg fired':>11}{'false touches':>15}{'loc med px':>12}{'recovery s med/max':>20}"
        f"{'sensitivity s med/max':>23}  margins -/+ edge, instant, sustained, projected",
    ]

    def num(v: float | None, fmt: str = ".3f") -> str:
        return "-" if v is None else format(v, fmt)

    for name, c in report["conditions"].items():
        loc = c["localisation_error_px"]
        rec = c["recovery_s"]
        recs = "-" if rec is None else f"{rec['median']:.2f} / {rec['max']:.2f}"
        sens = c.get("sensitivity_s")
        senses = "-" if sens is None else f"{sens['median']:.2f} / {sens['max']:.2f}"
        lines.append(
            f"{name:<12}{num(c['recall']):>8}{c['negatives_fired']:>6} / {c['negatives']:<3}{c['false_touches']:>15}"
            f"{num(loc['median'] if loc else None, '.2f'):>12}{recs:>20}{senses:>23}  "
            + ", ".join(f"{num(m['negative'], '+.3f')} / {num(m['positive'], '+.3f')}" for m in c["margins"].values())
        )
    return "\n".join(lines)
