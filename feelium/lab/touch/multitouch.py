"""Two hands, a palm and a hug: scripted scenes through the real touch pipeline (issue 17, point 4).

Every scene is rendered by the scene simulator (:mod:`feelium.sim`) in each of
the three protocol sessions, after :data:`WARMUP_S` of the same membrane
without hands, and replayed through :class:`feelium.touch.pipeline.TouchPipeline`
with the default ``[touch]`` config. The scenes' sizes are physical and stated
where they are built (:mod:`feelium.sim.hand`, :mod:`feelium.sim.body`), never
chosen by looking at detector scores; each run jitters the scene's place by up
to :data:`JITTER_PX`:

- ``one-finger``: one fingertip held 0.6 s (the paper's case, the baseline);
- ``two-finger-v``: one hand, index and middle fingertips 50 mm apart, pressed together;
- ``two-hands-5cm``: two hands from either side, fingertips 50 mm apart, pressed and lifted 0.2-0.3 s apart;
- ``two-partners``: two people, fingertips 150 mm apart, overlapping holds;
- ``swipe-cross``: a fingertip held while another hand's fingertip (from the other side) swipes past it,
  their pads' centres 18 mm apart as they pass (two 16 mm fingers side by side), at 160 mm/s;
- ``swipe-graze``: the same with the pads' centres 12 mm apart (the two fingertips, pointing at each other,
  graze): their pads' shadows merge while they pass;
- ``palm``: a hand pressed flat for 1.5 s;
- ``palm-and-finger``: a flat hand and, 120 mm away, a fingertip;
- ``hug``: a body leaning in, its chest pressed for 2 s.

Scoring: each event is given to the nearest true contact pressed then (within
:data:`MATCH_PX`, or the contact's own footprint for a palm or a hug; from
:data:`EARLY_S` before its onset to :data:`LATE_S` after its release), or is a
phantom. Per scene: true contacts, touches (event ids), contacts *missed* (no
id), *split* (ids beyond the first), id *swaps* (an id whose events move from
one true contact to another), phantom touches (ids with no true contact),
contact-kind confusion (the ``up`` event's ``contact`` against the truth) and
the localisation error (event position against the true footprint's centre,
camera px; 2 px = 1 mm).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from feelium.events import TouchEvent
from feelium.lab.report import finish_experiment
from feelium.lab.touch.ownership import tally_owners
from feelium.sim.camera import frame_times
from feelium.sim.hand import hand_parts
from feelium.sim.hand_paths import HandTrack, Keyframe, LeanTrack, Tremor
from feelium.sim.scene import HEIGHT, ROI, WIDTH, SceneRenderer, SceneState, Session, exposure_samples
from feelium.sim.sessions import SESSION_NAMES, session_presets
from feelium.sim.shadow import Ellipse
from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline

WARMUP_S = 2.0
JITTER_PX = 15.0
MATCH_PX = 40.0  # 20 mm: an event this close to a fingertip's true centre belongs to it
EARLY_S, LATE_S = 0.1, 0.4
KINDS = ("finger", "palm", "hug")
CX, CY = ROI[0] + ROI[2] / 2, ROI[1] + ROI[3] / 2


@dataclass(frozen=True)
class Truth:
    """One true contact: which actor, which of its footprints (-1: all of them together), when, what."""

    actor: int
    part: int
    on: float
    off: float
    kind: str


@dataclass(frozen=True)
class Scene:
    name: str
    duration: float
    hands: tuple[HandTrack, ...]
    leans: tuple[LeanTrack, ...]
    truths: tuple[Truth, ...]

    def state(self, t: float) -> SceneState:
        hands = tuple(p for p in (h.pose(t) for h in self.hands) if p is not None)
        return SceneState(hands=hands, leans=tuple(lean.lean(t) for lean in self.leans))

    def footprints(self, actor: int, t: float, px_per_mm: float) -> list[Ellipse]:
        """The contact ellipses of one actor (hands first, then leans) at ``t``."""
        if actor < len(self.hands):
            pose = self.hands[actor].pose(t)
            return [] if pose is None else hand_parts(pose, px_per_mm)[1]
        return self.leans[actor - len(self.hands)].lean(t).parts(px_per_mm)[1]

    def centre(self, truth: Truth, t: float, px_per_mm: float) -> tuple[float, float, float]:
        """The true footprint's centre (area-weighted over its ellipses) and its reach, camera px."""
        t = min(max(t, truth.on), truth.off - 1e-3)
        shapes = self.footprints(truth.actor, t, px_per_mm)
        if truth.part >= 0:
            shapes = shapes[truth.part : truth.part + 1]
        areas = np.array([e.ax * e.ay for e in shapes])
        xs, ys = np.array([e.cx for e in shapes]), np.array([e.cy for e in shapes])
        x, y = float(np.dot(areas, xs) / areas.sum()), float(np.dot(areas, ys) / areas.sum())
        reach = max(math.hypot(e.cx - x, e.cy - y) + max(e.ax, e.ay) for e in shapes)
        return x, y, reach


def _press(x: float, y: float, on: float, off: float, rng: np.random.Generator, **kw: Any) -> HandTrack:
    """A hand that comes down from 60 mm, presses during [on, off) and lifts again."""
    keys = (Keyframe(0.0, x, y, 60.0), Keyframe(on, x, y, 0.0), Keyframe(off, x, y, 0.0), Keyframe(off + 0.6, x, y, 60.0))
    return HandTrack(keys, ((on, off),), Tremor.draw(rng), **kw)


def _scene(name: str, rng: np.random.Generator) -> Scene:
    jx, jy = rng.uniform(-JITTER_PX, JITTER_PX, 2)
    x, y = CX + jx, CY + jy
    up, down = math.pi / 2, -math.pi / 2  # heading: where the wrist is (below, above)
    if name == "one-finger":
        return Scene(name, 2.6, (_press(x, y, 1.0, 1.6, rng),), (), (Truth(0, 0, 1.0, 1.6, "finger"),))
    if name == "two-finger-v":
        hand = _press(x - 50, y, 1.0, 2.4, rng, spread_mm=50.0)
        return Scene(name, 3.4, (hand,), (), (Truth(0, 0, 1.0, 2.4, "finger"), Truth(0, 1, 1.0, 2.4, "finger")))
    if name == "two-hands-5cm":
        left = _press(x - 50, y, 1.0, 2.4, rng, heading=up + 0.5, left=True)
        right = _press(x + 50, y, 1.2, 2.7, rng, heading=up - 0.5)
        return Scene(name, 3.6, (left, right), (), (Truth(0, 0, 1.0, 2.4, "finger"), Truth(1, 0, 1.2, 2.7, "finger")))
    if name == "two-partners":
        a, b = _press(x - 150, y, 1.0, 2.6, rng), _press(x + 150, y, 1.3, 2.3, rng)
        return Scene(name, 3.4, (a, b), (), (Truth(0, 0, 1.0, 2.6, "finger"), Truth(1, 0, 1.3, 2.3, "finger")))
    if name in ("swipe-cross", "swipe-graze"):
        gap = 18.0 if name == "swipe-cross" else 12.0  # px either side: pad centres 18 mm / 12 mm apart
        held = _press(x, y + gap, 0.8, 3.4, rng)
        sy = y - gap
        keys = (
            Keyframe(0.0, x - 170, sy, 60.0), Keyframe(1.3, x - 160, sy, 0.0), Keyframe(1.4, x - 160, sy, 0.0),
            Keyframe(2.6, x + 160, sy, 0.0), Keyframe(2.7, x + 160, sy, 0.0), Keyframe(3.3, x + 170, sy, 60.0),
        )  # fmt: skip
        swipe = HandTrack(keys, ((1.3, 2.7),), Tremor.draw(rng), heading=down)
        return Scene(name, 4.0, (held, swipe), (), (Truth(0, 0, 0.8, 3.4, "finger"), Truth(1, 0, 1.3, 2.7, "finger")))
    if name == "palm":
        return Scene(name, 3.2, (_press(x, y + 40, 1.0, 2.5, rng, flat=True),), (), (Truth(0, -1, 1.0, 2.5, "palm"),))
    if name == "palm-and-finger":
        palm = _press(x - 110, y + 40, 1.0, 2.6, rng, flat=True)
        finger = _press(x + 130, y, 1.3, 2.2, rng)
        return Scene(name, 3.4, (palm, finger), (), (Truth(0, -1, 1.0, 2.6, "palm"), Truth(1, 0, 1.3, 2.2, "finger")))
    if name == "hug":
        keys = (Keyframe(0.0, x, y, 150.0), Keyframe(1.0, x, y, 0.0), Keyframe(3.0, x, y, 0.0), Keyframe(3.8, x, y, 150.0))
        return Scene(name, 4.2, (), (LeanTrack(keys, ((1.0, 3.0),)),), (Truth(0, -1, 1.0, 3.0, "hug"),))
    raise ValueError(f"unknown scene {name!r}; expected one of {', '.join(SCENES)}")


SCENES = (
    "one-finger", "two-finger-v", "two-hands-5cm", "two-partners", "swipe-cross", "swipe-graze", "palm",
    "palm-and-finger", "hug",
)  # fmt: skip


def run_scene(scene: Scene, session: Session, rng: np.random.Generator, config: TouchConfig) -> list[TouchEvent]:
    """Render ``scene`` (after a hand-free warm-up) and replay it through the pipeline; the events after 0 s."""
    renderer = SceneRenderer(session, rng, width=WIDTH, height=HEIGHT, roi=ROI)
    pipeline = TouchPipeline(config, (WIDTH, HEIGHT), ROI)
    for t in np.arange(-WARMUP_S, -0.25, 1.0 / session.sensor.fps):
        pipeline.process(float(t), renderer.frame(float(t), SceneState()))
    events: list[TouchEvent] = []
    for t in frame_times(session.sensor, scene.duration, rng):
        t = float(t)
        frame = renderer.frame(t, exposure_samples(scene.state, t, session.sensor.exposure_s))
        events.extend(pipeline.process(t, frame).events)
    events.extend(pipeline.finish())
    return events


def score(scene: Scene, events: list[TouchEvent], px_per_mm: float) -> dict[str, Any]:
    """Match events to true contacts and count what went wrong (see the module docstring)."""
    owner: dict[int, list[int]] = {}  # event id -> the true contact of each of its events (-1: none)
    errors: dict[int, list[float]] = {i: [] for i in range(len(scene.truths))}
    final: dict[int, str | None] = {}
    areas: dict[str, list[float]] = {k: [] for k in KINDS}
    for e in events:
        best, best_d = -1, math.inf
        for i, truth in enumerate(scene.truths):
            if not truth.on - EARLY_S <= e.t <= truth.off + LATE_S:
                continue
            x, y, reach = scene.centre(truth, e.t, px_per_mm)
            d = math.hypot(e.x - x, e.y - y)
            if d <= max(MATCH_PX, reach) and d < best_d:
                best, best_d = i, d
        owner.setdefault(e.id, []).append(best)
        if best >= 0 and e.phase != "up":
            errors[best].append(best_d)
        if e.phase == "up":
            final[e.id] = e.shape.contact if e.shape is not None else None
            if e.shape is not None and e.shape.area_mm2 is not None and best >= 0:
                areas[scene.truths[best].kind].append(e.shape.area_mm2)
    tally = tally_owners(owner, final, [truth.kind for truth in scene.truths], KINDS)
    return {
        "truths": len(scene.truths),
        "touches": tally["touches"],
        "missed": tally["missed"],
        "split": tally["split"],
        "swaps": tally["swaps"],
        "phantoms": tally["phantoms"],
        "confusion": tally["confusion"],
        "errors_px": [float(np.median(v)) for v in errors.values() if v],
        "areas_mm2": areas,
    }


def run_experiment(
    *, seed: int = 1, reps: int = 1, scenes: tuple[str, ...] = SCENES, config: TouchConfig = TouchConfig()
) -> dict[str, Any]:
    """Every scene in every session ``reps`` times; per-scene totals."""
    sessions = session_presets(seed)
    report: dict[str, Any] = {"seed": seed, "reps": reps, "sessions": list(SESSION_NAMES), "scenes": {}}
    for name in scenes:
        runs = []
        for rep in range(reps):
            for k, session_name in enumerate(SESSION_NAMES):
                rng = np.random.default_rng([seed, zlib.crc32(name.encode()), rep, k])
                scene = _scene(name, rng)
                events = run_scene(scene, sessions[session_name], rng, config)
                runs.append(score(scene, events, sessions[session_name].shadow.px_per_mm))
        report["scenes"][name] = _total(runs)
    return report


def _total(runs: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {"runs": len(runs)}
    for key in ("truths", "touches", "missed", "split", "swaps", "phantoms"):
        out[key] = sum(r[key] for r in runs)
    confusion = {k: {c: sum(r["confusion"][k][c] for r in runs) for c in (*KINDS, "none")} for k in KINDS}
    out["confusion"] = {k: v for k, v in confusion.items() if sum(v.values())}
    errors = [e for r in runs for e in r["errors_px"]]
    out["loc_error_px"] = None if not errors else {"median": float(np.median(errors)), "max": float(max(errors))}
    areas = {k: [a for r in runs for a in r["areas_mm2"][k]] for k in KINDS}
    out["footprint_mm2"] = {k: float(np.median(v)) for k, v in areas.items() if v}
    return out


def format_table(report: dict[str, Any]) -> str:
    lines = [
        f"multitouch: {report['reps']} x {len(report['sessions'])} sessions per scene (seed {report['seed']})",
        f"{'scene':<17}{'contacts':>9}{'touches':>8}{'missed':>7}{'split':>6}{'swaps':>6}{'phantom':>8}"
        f"{'kind ok':>9}{'loc med/max px':>16}  footprint mm2",
    ]
    for name, s in report["scenes"].items():
        ok = sum(v[k] for k, v in s["confusion"].items())
        total = sum(sum(v.values()) for v in s["confusion"].values())
        loc = s["loc_error_px"]
        locs = "-" if loc is None else f"{loc['median']:.1f} / {loc['max']:.1f}"
        feet = ", ".join(f"{k} {v:.0f}" for k, v in s["footprint_mm2"].items())
        lines.append(
            f"{name:<17}{s['truths']:>9}{s['touches']:>8}{s['missed']:>7}{s['split']:>6}{s['swaps']:>6}"
            f"{s['phantoms']:>8}{f'{ok}/{total}':>9}{locs:>16}  {feet}"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m feelium.lab.touch.multitouch [--reps N] [--seed S] [--scene NAME ...] [--json FILE]``."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m feelium.lab.touch.multitouch", description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--reps", type=int, default=1, help="runs per scene and session (default 1)")
    parser.add_argument("--scene", action="append", choices=SCENES, help="only these scenes (repeatable)")
    parser.add_argument("--json", help="write the report here")
    args = parser.parse_args(argv)
    report = run_experiment(seed=args.seed, reps=args.reps, scenes=tuple(args.scene or SCENES))
    return finish_experiment(format_table(report), report, args.json, progressed=False)


if __name__ == "__main__":
    raise SystemExit(main())
