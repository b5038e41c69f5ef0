"""The six exchanges end to end in sim, through the real touch pipeline.

A simulated hand (or a pressed palm or body) touches the membrane in the
simulated rear camera; the touch pipeline turns the frames into touch events,
annotated with region and projector point as the touch service does; the
projector service's engine publishes InteractionEvents on the hub bus (what
the HTTP API streams to the wearer); and the projector's frame shows the
answer where the skin was touched, checked in projector pixels against the
simulator's own fisheye warp (the truth, not the renderer's calibration code).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from feelium.daemon.config import Config
from feelium.events import InteractionEvent, TouchEvent, WearerAction
from feelium.hub import Hub
from feelium.skin.annotation import annotate
from feelium.skin.regions import Regions
from feelium.projector.display import SimDisplay
from feelium.projector.service import ProjectorService
from feelium.lab.sim import protocol, scripts
from feelium.sim.sessions import session_presets
from feelium.sim.hand import Blob
from feelium.sim.hand_paths import Keyframe, LeanTrack
from feelium.sim.projection import FisheyeWarp
from feelium.sim.scene import HEIGHT, ROI, WIDTH
from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline
from tests.projector.helpers import centroid, truth_calibration

pytestmark = pytest.mark.slow


@dataclasses.dataclass(frozen=True)
class Pressed(scripts.Script):
    """A script plus soft bodies pressed flat on the membrane (a palm, a leaning torso) during given intervals."""

    press: tuple[tuple[float, float, float, float, float, float], ...] = ()  # (t_on, t_off, x, y, rx, ry)
    lean: LeanTrack | None = None  # a body stepping in at its first key, its chest pressed during the track's contacts

    def state(self, t: float):
        state = super().state(t)
        pressed = tuple(Blob(x, y, rx, ry, 0.0) for (on, off, x, y, rx, ry) in self.press if on <= t < off)
        near = self.lean is not None and t >= self.lean.keys[0].t
        leans = state.leans + ((self.lean.lean(t),) if self.lean is not None and near else ())
        return dataclasses.replace(state, blobs=state.blobs + pressed, leans=leans)


def at_uv(u: float, v: float) -> tuple[float, float]:
    x, y, w, h = ROI
    return x + u * w, y + v * h


class SimSkin:
    """Simulated rear camera -> touch pipeline -> hub bus -> projector service, stepped on each camera frame."""

    def __init__(self) -> None:
        self.calibration = truth_calibration()
        self.warp = FisheyeWarp()
        self.hub = Hub()
        config = Config()
        self.service = ProjectorService(config.projector, config.interactions, self.hub, SimDisplay(), self.calibration)
        self.regions = Regions.from_config(config.interactions)
        self.inputs = self.hub.bus.subscribe((TouchEvent, WearerAction), maxsize=4096)
        self.wearer = self.hub.bus.subscribe([InteractionEvent], maxsize=4096)
        self.pipeline = TouchPipeline(TouchConfig(), (WIDTH, HEIGHT), ROI)
        self.session = session_presets(1)["s1"]
        self.offset = 0.0
        self.now = 0.0
        self.seen: list[InteractionEvent] = []
        self.touches: list[TouchEvent] = []

    def play(self, script: scripts.Script, actions: tuple[WearerAction, ...] = (), seed: int = 1) -> float:
        """Run ``script`` (its times shifted to follow what was played before); returns the shift."""
        shift = self.offset
        pending = sorted(actions, key=lambda a: a.t)
        for t, frame in protocol.render_frames(script, self.session, np.random.default_rng(seed)):
            now = shift + t
            while pending and shift + pending[0].t <= now:
                action = pending.pop(0)
                self.hub.bus.publish(dataclasses.replace(action, t=shift + action.t))
            for event in self.pipeline.process(now, frame).events:
                annotated = annotate(event, self.calibration, self.regions)
                self.touches.append(annotated)
                self.hub.bus.publish(annotated)
            self.service.step_engine(self.inputs, now)
            self.seen += self.wearer.drain()
            self.now = now
        self.offset = self.now + 0.1
        return shift

    def names(self) -> list[tuple[str, str]]:
        return [(e.name, e.phase) for e in self.seen]

    def answer_pixels(self, kinds: tuple[str, ...]) -> np.ndarray:
        """Projector pixels the answers of ``kinds`` change at the current instant (the frame against the bare face)."""
        renderer = self.service.renderer
        answers = [a for a in self.service.engine.answers(self.now) if a.kind in kinds]
        assert answers, f"no {kinds} answer on the skin at {self.now:.2f} s"
        frame = renderer.render(self.now, None, answers)
        bare = renderer.render(self.now, None, [])
        diff = np.abs(frame.astype(np.int16) - bare.astype(np.int16)).sum(axis=2)
        diff[diff < 40] = 0
        return diff

    def on_projector(self, x: float, y: float) -> tuple[float, float]:
        """The simulator's true projector pixel of camera point (x, y)."""
        px, py = self.warp.camera_to_projector(np.array([x]), np.array([y]))
        return float(px[0]), float(py[0])


def _assert_answer_at(skin: SimSkin, kinds: tuple[str, ...], x: float, y: float, tolerance_px: float = 25.0) -> None:
    got = centroid(skin.answer_pixels(kinds))
    want = skin.on_projector(x, y)
    assert np.hypot(got[0] - want[0], got[1] - want[1]) < tolerance_px, (kinds, got, want)


def _tap(target: tuple[float, float], seed: int) -> scripts.Script:
    return scripts.tap(np.random.default_rng(seed), target, (0.0, 0.0), ROI)


def _landing(script: scripts.Script) -> tuple[float, float]:
    contact = script.labels().contacts[0]
    return contact.position_at(contact.t_on)


def test_greeting_pat_on_the_head_ripples_to_the_wearer_and_pulses_on_the_skin():
    skin = SimSkin()
    script = _tap(at_uv(0.5, 0.2), seed=3)
    skin.play(script)
    pats = [e for e in skin.seen if e.name == "greeting_pat"]
    assert [(e.phase, e.region, e.detail["taps"]) for e in pats] == [("pat", "head", 1)]
    x, y = _landing(script)
    assert np.hypot(pats[0].x - x, pats[0].y - y) < 15.0  # the wearer's ripple is where the finger landed
    skin.now = pats[0].t + 0.3  # the rings have opened a little
    _assert_answer_at(skin, ("ripple", "warm_pulse"), x, y)


def test_peck_on_a_cheek_blooms_a_heart_there_and_the_wearers_heart_comes_back():
    skin = SimSkin()
    script = _tap(at_uv(0.73, 0.58), seed=4)
    skin.play(script, actions=(WearerAction("heart", script.duration - 0.3),))
    assert skin.names() == [("peck", "bloom"), ("peck", "returned")]
    assert skin.seen[0].region == "cheek_right" and skin.seen[1].region == "cheek_right"
    x, y = _landing(script)
    answers = [a for a in skin.service.engine.answers(skin.now) if a.kind == "heart"]
    assert sorted(a.detail["from"] for a in answers) == ["partner", "wearer"]
    _assert_answer_at(skin, ("heart",), x, y)


def test_palm_to_palm_glows_on_both_sides_and_merges_where_the_palm_is():
    skin = SimSkin()
    x, y = at_uv(0.62, 0.78)
    script = Pressed("hold", 3.4, press=((0.8, 3.0, x, y, 90.0, 80.0),))  # a flat hand: 45 x 40 mm semi-axes at 2 px/mm
    skin.play(script, actions=(WearerAction("palm_raise", 0.3),))
    assert skin.names()[:3] == [("palm_to_palm", "wearer"), ("palm_to_palm", "partner"), ("palm_to_palm", "merge")]
    assert skin.names()[-1] == ("palm_to_palm", "end")
    partner = skin.seen[1]
    assert partner.detail["contact_area_mm2"] >= Config().touch.palm_min_area_mm2  # the pipeline saw a palm
    skin.now = skin.seen[2].t + 1.0  # the wearer's glow has glided onto the partner's palm
    _assert_answer_at(skin, ("palm_glow",), x, y)


def test_finger_drawing_streams_strokes_and_a_correct_guess_ignites_them_on_the_skin():
    skin = SimSkin()
    script = scripts.swipe(np.random.default_rng(5), at_uv(0.35, 0.45), (0.0, 0.0), ROI)
    skin.play(script)
    names = skin.names()
    assert names[0] == ("drawing", "start") and ("drawing", "stroke") in names and ("drawing", "stroke_end") in names
    path = script.labels().contacts[0].path
    sent = np.array([p for e in skin.seen if e.phase == "stroke" for p in e.detail["points"]])
    cam = np.column_stack([ROI[0] + sent[:, 0] * ROI[2], ROI[1] + sent[:, 1] * ROI[3]])
    # Every streamed point lies on the true stroke (within the pipeline's localisation error).
    dist = np.min(np.hypot(cam[:, None, 0] - path[None, :, 1], cam[:, None, 1] - path[None, :, 2]), axis=1)
    assert np.median(dist) < 12.0
    lit = skin.answer_pixels(("stroke",)) > 0
    covered = [skin.on_projector(px, py) for _, px, py in path[:: max(1, len(path) // 10)]]
    near = [lit[max(0, int(v) - 12) : int(v) + 13, max(0, int(u) - 12) : int(u) + 13].any() for u, v in covered]
    assert np.mean(near) >= 0.6, near  # the drawn stroke is on the skin along the true path
    prompt = next(a for a in skin.service.engine.answers(skin.now) if a.kind == "prompt")
    word = prompt.detail["text"].removeprefix("draw: ")
    skin.play(Pressed("empty", 0.8), actions=(WearerAction("guess", 0.2, {"word": "wrong"}), WearerAction("guess", 0.5, {"word": word})))
    assert skin.names()[-2:] == [("drawing", "wrong_guess"), ("drawing", "ignite")]
    mid = path[len(path) // 2]
    _assert_answer_at(skin, ("ignite",), mid[1], mid[2], tolerance_px=60.0)


def test_lean_in_hug_sets_the_whole_skin_breathing_until_release():
    skin = SimSkin()
    x, y = at_uv(0.5, 0.55)
    # The body steps in after 1.5 s of empty membrane (the reference forms), leans in, presses its chest 2.5 s.
    keys = (Keyframe(1.5, x, y, 150.0), Keyframe(2.5, x, y, 0.0), Keyframe(5.0, x, y, 0.0), Keyframe(5.8, x, y, 150.0))
    skin.play(Pressed("hold", 6.2, lean=LeanTrack(keys, ((2.5, 5.0),))), seed=6)  # a chest pressing 200 x 160 mm
    assert ("hug", "start") in skin.names() and skin.names()[-1] == ("hug", "end")
    start = next(e for e in skin.seen if e.name == "hug")
    assert start.detail["contact_area_mm2"] >= Config().touch.hug_min_area_mm2  # the pipeline saw a hug
    skin.now = start.t + 1.0
    lit = skin.answer_pixels(("breathing",)) > 0
    covered = skin.service.renderer.covered
    assert lit[covered].mean() > 0.8  # the whole skin, not a spot


def test_wearer_shimmer_invites_drifts_closer_and_a_touch_accepts_with_a_bounce():
    skin = SimSkin()
    script = _tap(at_uv(0.5, 0.5), seed=7)
    skin.play(script, actions=(WearerAction("shimmer", 0.2),))
    names = skin.names()
    assert names[0] == ("invite", "shimmer") and ("invite", "accepted") in names
    sent = skin.service.counters["motions_sent"]
    assert sent >= 2  # drift closer (forward), then the bounce's up (the down follows)
    active = skin.hub.motion.active(skin.now)
    assert active is None or active.source == "interaction"
    accepted = next(e for e in skin.seen if e.phase == "accepted")
    x, y = _landing(script)
    skin.now = accepted.t + 0.2
    _assert_answer_at(skin, ("warm_pulse",), x, y)
