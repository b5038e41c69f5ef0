"""The six exchanges of the paper as one pure state machine.

Inputs: touch events (from the touch pipeline, optionally annotated with a
``region``), wearer actions (from the headset) and the time ``now`` on the
caller's clock (the engine never reads a clock, so replays and tests are
exact). Outputs: :class:`~feelium.events.InteractionEvent` for the wearer's
view, :class:`~feelium.interactions.answers.Answer` for the projector, and
:class:`MotionReply` for the flight controller's dead-man path.

- greeting pat: a tap on the head -> ``greeting_pat/pat`` (with the tap count of
  the pat) and a ripple plus warm pulse at the spot.
- palm-to-palm: a contact the touch pipeline calls a ``palm`` held ``palm_hold_s`` -> ``palm_to_palm/partner``
  and a palm glow; the wearer's ``palm_raise`` -> ``palm_to_palm/wearer`` and a
  second glow in the palm zone; both at once -> ``palm_to_palm/merge``: the
  wearer's glow glides onto the partner's and they merge; either leaving -> ``end``.
- peck: a tap on a cheek -> ``peck/bloom`` and a small heart there; the wearer's
  ``heart`` -> ``peck/returned`` and a heart back on the last pecked cheek.
- finger drawing: a ``finger`` contact that travels ``stroke_min_px`` -> ``drawing/start``
  (new round, secret word shown to the partner), then ``drawing/stroke`` with
  each new point, live strokes on the skin; a correct ``guess`` -> ``drawing/ignite``
  and the drawing ignites; a wrong one -> ``drawing/wrong_guess``.
- lean-in hug: a ``hug`` contact held ``hug_hold_s`` -> ``hug/start`` and the whole
  skin breathes, until no hug contact is left -> ``hug/end``.

What touched is the event's ``contact`` (``finger``, ``palm``, ``hug``: the pipeline's
footprint in mm, :mod:`feelium.touch.shape`), never an area in camera pixels, so the
rules mean the same at every camera resolution and lens; an event without a shape (a
replay of an older stream) is a fingertip.
- invite: the wearer's ``shimmer`` -> ``invite/shimmer``, a shimmer and a
  "drift closer" motion; the partner's next touch during it -> ``invite/accepted``,
  a warm pulse there and a "gentle bounce" (up, then down).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

from feelium.events import ContactKind, InteractionEvent, TouchEvent, WearerAction
from feelium.interactions.answers import Answer
from feelium.interactions.config import InteractionsConfig
from feelium.skin.regions import Regions
from feelium.interactions.wordgame import choose_word, display_word, is_correct

RIPPLE_S = 1.2
PULSE_S = 1.6
HEART_S = 2.0
GLIDE_S = 0.8
FADE_S = 1.5
PROMPT_S = 4.0
# A drawing round lasts while someone keeps drawing or guessing, so without bounds its strokes pile up: a
# 30-minute soak drew ~1200 strokes and the projector's frame cost grew 3.5x with them. The oldest strokes
# leave the skin beyond MAX_STROKES, and a stroke that keeps going past MAX_STROKE_POINTS goes on as a new one.
MAX_STROKES = 64
MAX_STROKE_POINTS = 256
_STALE_MOTION_S = 0.3  # a motion reply more late than this is dropped, never sent out of time
_CONTACT_RANK: dict[str, int] = {"finger": 0, "palm": 1, "hug": 2}


@dataclass(frozen=True)
class MotionReply:
    """A small motion for the dead-man path: ``name`` held ``hold_s`` from ``at``."""

    name: str
    at: float
    hold_s: float
    reason: str


@dataclass
class _Contact:
    id: int
    t_down: float
    x: float
    y: float
    u: float
    v: float
    region: str | None
    area: int
    contact: ContactKind = "finger"  # the largest kind seen while down (a palm lands heel first, a hug grows)
    area_mm2: float | None = None
    hug_since: float | None = None  # when it first showed as a hug
    length: float = 0.0
    stroke: int | None = None  # stroke number once it travels far enough
    palm: bool = False
    sent_points: int = 0
    points: list[tuple[float, float]] = field(default_factory=list)


@dataclass
class _DrawingRound:
    number: int
    entry: str
    last_activity: float
    strokes: dict[int, tuple[tuple[float, float], ...]] = field(default_factory=dict)
    ignited_at: float | None = None


@dataclass(frozen=True)
class Step:
    events: tuple[InteractionEvent, ...]
    motions: tuple[MotionReply, ...]


class InteractionEngine:
    """Touch events and wearer actions in; interaction events, answers and motion replies out."""

    def __init__(self, config: InteractionsConfig, regions: Regions | None = None) -> None:
        self.config = config
        self.regions = regions if regions is not None else Regions.from_config(config)
        self._contacts: dict[int, _Contact] = {}
        self._answers: dict[str, Answer] = {}
        self._pending: list[InteractionEvent] = []
        self._motions: list[MotionReply] = []
        self._serial = 0
        self._last_head_tap = -math.inf
        self._pat_taps = 0
        self._last_peck: tuple[float, float, float, str] | None = None  # t, u, v, region
        self._wearer_palm_since: float | None = None
        self._palm_contact: int | None = None
        self._palm_merged = False
        self._hugging = False
        self._shimmer_until = -math.inf
        self._rounds = 0
        self._round: _DrawingRound | None = None
        self._strokes = 0
        self.counts: dict[str, int] = {"touch": 0, "action": 0, "ignored": 0, "motions_dropped": 0}

    # ---- inputs -------------------------------------------------------------------------------

    def touch(self, event: TouchEvent, now: float) -> None:
        """Feed one touch event (``down``/``move``/``up``) seen at ``now``."""
        self.counts["touch"] += 1
        if not (math.isfinite(event.u) and math.isfinite(event.v)):
            self.counts["ignored"] += 1
            return
        region = event.extra.get("region") if "region" in event.extra else self.regions.region_at(event.u, event.v)
        contact = self._contacts.get(event.id)
        if event.phase == "down" or contact is None:
            contact = _Contact(event.id, now, event.x, event.y, event.u, event.v, region, event.area, points=[(event.u, event.v)])
            self._contacts[event.id] = contact
            _take_shape(contact, event, now)
            self._on_first_touch(contact, event, now)
            if event.phase == "down":
                return
        self._on_move(contact, event, now)
        if event.phase == "up":
            self._on_up(contact, event, now)
            del self._contacts[event.id]

    def action(self, action: WearerAction, now: float) -> None:
        """Feed one wearer action received at ``now``."""
        self.counts["action"] += 1
        name = action.action
        if name == "heart":
            self._heart_back(now)
        elif name == "palm_raise":
            self._palm_raise(now)
        elif name == "palm_lower":
            self._palm_lower(now)
        elif name == "shimmer":
            self._shimmer(now)
        elif name == "guess":
            self._guess(str(action.detail.get("word", "")), now)
        else:
            self.counts["ignored"] += 1

    def tick(self, now: float) -> Step:
        """Advance time: time-based rules fire, due motions are released, old answers dropped."""
        self._check_palm(now)
        self._check_hug(now)
        self._check_drawing(now)
        self._answers = {k: a for k, a in self._answers.items() if a.alive(now)}
        due = [m for m in self._motions if m.at <= now]
        self._motions = [m for m in self._motions if m.at > now]
        fresh = []
        for m in due:
            if now - m.at > _STALE_MOTION_S:
                self.counts["motions_dropped"] += 1
            else:
                fresh.append(m)
        events, self._pending = tuple(self._pending), []
        return Step(events, tuple(fresh))

    def answers(self, now: float) -> tuple[Answer, ...]:
        """What the projector should draw at ``now``, oldest first."""
        return tuple(sorted((a for a in self._answers.values() if a.alive(now)), key=lambda a: a.t0))

    # ---- helpers ------------------------------------------------------------------------------

    def _emit(
        self, name: str, phase: str, now: float, contact: _Contact | None = None, region: str | None = None, **detail: Any
    ) -> None:
        x = y = None
        if contact is not None:
            x, y, region = contact.x, contact.y, contact.region
        self._pending.append(InteractionEvent(name, phase, now, x, y, region, detail))

    def _answer(self, key: str | None, answer: Answer) -> None:
        if key is None:
            self._serial += 1
            key = f"{answer.kind}:{self._serial}"
        self._answers[key] = answer

    def _end_answer(self, key: str, now: float, fade_s: float = FADE_S) -> None:
        answer = self._answers.get(key)
        if answer is not None and answer.until > now + fade_s:
            self._answers[key] = replace(answer, until=now + fade_s, detail={**answer.detail, "fade_from": now})

    # ---- touch rules --------------------------------------------------------------------------

    def _on_first_touch(self, contact: _Contact, event: TouchEvent, now: float) -> None:
        if now < self._shimmer_until:
            self._shimmer_until = -math.inf
            self._end_answer("shimmer", now, 0.5)
            self._emit("invite", "accepted", now, contact)
            self._answer(None, Answer("warm_pulse", now, contact.u, contact.v, now + PULSE_S))
            bounce = self.config.bounce_hold_s
            self._motions.append(MotionReply("up", now, bounce, "gentle_bounce"))
            self._motions.append(MotionReply("down", now + bounce, bounce, "gentle_bounce"))

    def _on_move(self, contact: _Contact, event: TouchEvent, now: float) -> None:
        if math.isfinite(event.x) and math.isfinite(event.y):
            contact.length += math.hypot(event.x - contact.x, event.y - contact.y)
            contact.x, contact.y = event.x, event.y
        contact.u, contact.v = event.u, event.v
        contact.area = event.area
        _take_shape(contact, event, now)
        if (contact.u, contact.v) != contact.points[-1]:
            contact.points.append((contact.u, contact.v))
        if contact.stroke is None and contact.contact == "finger" and contact.length >= self.config.stroke_min_px:
            self._start_stroke(contact, now)
        if contact.stroke is not None and len(contact.points) > MAX_STROKE_POINTS:
            self._emit("drawing", "stroke_end", now, contact, stroke=contact.stroke)
            contact.points, contact.sent_points = contact.points[-1:], 0
            self._start_stroke(contact, now)
        if contact.stroke is not None:
            new = contact.points[contact.sent_points :]
            if new:
                contact.sent_points = len(contact.points)
                self._emit("drawing", "stroke", now, contact, stroke=contact.stroke, points=[[round(u, 4), round(v, 4)] for u, v in new])
                points = tuple(contact.points)
                # Round and stroke number: the renderer keeps each stroke drawn by this identity (projector/strokes.py).
                detail = {"points": points, "stroke": contact.stroke, "round": self._rounds}
                self._answer(f"stroke:{contact.stroke}", Answer("stroke", contact.t_down, contact.u, contact.v, detail=detail))
                if self._round is not None:
                    self._round.strokes[contact.stroke] = points
                    self._round.last_activity = now

    def _start_stroke(self, contact: _Contact, now: float) -> None:
        if self._round is None or self._round.ignited_at is not None:
            self._rounds += 1
            entry = choose_word(self.config.words, self.config.seed, self._rounds)
            self._round = _DrawingRound(self._rounds, entry, now)
            self._emit("drawing", "start", now, contact, round=self._rounds)
            self._answer("prompt", Answer("prompt", now, 0.5, 0.93, now + PROMPT_S, {"text": f"draw: {display_word(entry)}"}))
        self._strokes += 1
        contact.stroke = self._strokes
        old = self._strokes - MAX_STROKES
        self._answers.pop(f"stroke:{old}", None)
        if self._round is not None:
            self._round.strokes.pop(old, None)

    def _on_up(self, contact: _Contact, event: TouchEvent, now: float) -> None:
        if contact.stroke is not None:
            self._emit("drawing", "stroke_end", now, contact, stroke=contact.stroke)
            return
        if contact.palm:
            return  # the palm rule ends in _check_palm once the contact is gone
        if event.kind != "tap":
            return
        if contact.region == "head":
            self._pat_taps = self._pat_taps + 1 if now - self._last_head_tap <= self.config.pat_window_s else 1
            self._last_head_tap = now
            self._emit("greeting_pat", "pat", now, contact, taps=self._pat_taps)
            self._answer(None, Answer("ripple", now, contact.u, contact.v, now + RIPPLE_S))
            self._answer(None, Answer("warm_pulse", now, contact.u, contact.v, now + PULSE_S))
        elif contact.region in ("cheek_left", "cheek_right"):
            self._last_peck = (now, contact.u, contact.v, contact.region)
            self._emit("peck", "bloom", now, contact)
            self._answer(None, Answer("heart", now, contact.u, contact.v, now + HEART_S, {"from": "partner"}))

    def _check_palm(self, now: float) -> None:
        cfg = self.config
        if self._palm_contact is not None and self._palm_contact not in self._contacts:
            self._palm_contact = None
            self._palm_merged = False
            self._emit("palm_to_palm", "end", now, who="partner")
            self._end_answer("palm:partner", now)
            if self._wearer_palm_since is not None:
                self._answer("palm:wearer", self._wearer_glow(now))
        if self._palm_contact is None:
            for contact in self._contacts.values():
                if contact.stroke is None and contact.contact == "palm" and now - contact.t_down >= cfg.palm_hold_s:
                    contact.palm = True
                    self._palm_contact = contact.id
                    self._emit("palm_to_palm", "partner", now, contact, area=contact.area, contact_area_mm2=contact.area_mm2)
                    self._answer("palm:partner", Answer("palm_glow", now, contact.u, contact.v, detail={"side": "partner"}))
                    break
        if self._palm_contact is not None:
            contact = self._contacts[self._palm_contact]
            partner = self._answers.get("palm:partner")
            if partner is not None and (partner.u, partner.v) != (contact.u, contact.v):
                self._answers["palm:partner"] = replace(partner, u=contact.u, v=contact.v)
            if self._wearer_palm_since is not None and not self._palm_merged:
                self._palm_merged = True
                self._emit("palm_to_palm", "merge", now, contact)
                start = self._answers.get("palm:wearer")
                fu, fv = (start.u, start.v) if start is not None else self.regions.centre("palm_zone")
                self._answer("palm:wearer", Answer("palm_glow", now, contact.u, contact.v, detail={
                    "side": "wearer", "from_u": fu, "from_v": fv, "glide_s": GLIDE_S, "merged": True}))

    def _wearer_glow(self, now: float) -> Answer:
        u, v = self.regions.centre("palm_zone")
        return Answer("palm_glow", now, u, v, detail={"side": "wearer"})

    def _check_hug(self, now: float) -> None:
        hugs = [c for c in self._contacts.values() if c.contact == "hug" and c.hug_since is not None]
        if not self._hugging:
            if hugs and now - min(c.hug_since for c in hugs if c.hug_since is not None) >= self.config.hug_hold_s:
                self._hugging = True
                widest = max(hugs, key=lambda c: c.area)
                self._emit("hug", "start", now, area=widest.area, contact_area_mm2=widest.area_mm2)
                self._answer("breathing", Answer("breathing", now, 0.5, 0.5))
        elif not hugs:
            self._hugging = False
            self._emit("hug", "end", now)
            self._end_answer("breathing", now, 2.0)

    def _check_drawing(self, now: float) -> None:
        rnd = self._round
        if rnd is None:
            return
        if rnd.ignited_at is not None:
            if now - rnd.ignited_at >= self.config.ignite_s:
                self._end_round(now, "ignited")
        elif now - rnd.last_activity >= self.config.drawing_idle_s:
            self._emit("drawing", "end", now, reason="idle", word=display_word(rnd.entry))
            self._end_round(now, "idle")

    def _end_round(self, now: float, reason: str) -> None:
        self._round = None
        for key in [k for k in self._answers if k.startswith("stroke:")]:
            del self._answers[key]
        if reason == "ignited":
            self._emit("drawing", "end", now, reason=reason)

    # ---- wearer rules -------------------------------------------------------------------------

    def _heart_back(self, now: float) -> None:
        peck = self._last_peck
        if peck is not None and now - peck[0] <= self.config.heart_reply_s:
            _, u, v, region = peck
        else:
            region = "cheek_right"
            u, v = self.regions.centre(region)
        self._emit("peck", "returned", now, region=region)
        self._answer(None, Answer("heart", now, u, v, now + HEART_S, {"from": "wearer"}))

    def _palm_raise(self, now: float) -> None:
        if self._wearer_palm_since is not None:
            return
        self._wearer_palm_since = now
        self._emit("palm_to_palm", "wearer", now)
        self._answer("palm:wearer", self._wearer_glow(now))

    def _palm_lower(self, now: float) -> None:
        if self._wearer_palm_since is None:
            return
        self._wearer_palm_since = None
        self._palm_merged = False
        self._emit("palm_to_palm", "end", now, who="wearer")
        self._end_answer("palm:wearer", now)

    def _shimmer(self, now: float) -> None:
        self._shimmer_until = now + self.config.shimmer_s
        self._emit("invite", "shimmer", now)
        self._answer("shimmer", Answer("shimmer", now, 0.5, 0.5, self._shimmer_until))
        self._motions.append(MotionReply("forward", now, self.config.drift_hold_s, "drift_closer"))

    def _guess(self, word: str, now: float) -> None:
        rnd = self._round
        if rnd is None or rnd.ignited_at is not None:
            self._emit("drawing", "no_round", now, guess=word)
            return
        rnd.last_activity = now
        if is_correct(word, rnd.entry):
            rnd.ignited_at = now
            self._emit("drawing", "ignite", now, guess=word, word=display_word(rnd.entry), round=rnd.number)
            strokes = tuple(rnd.strokes.values())
            u, v = _centroid(strokes)
            self._answer("ignite", Answer("ignite", now, u, v, now + self.config.ignite_s, {"strokes": strokes}))
        else:
            self._emit("drawing", "wrong_guess", now, guess=word)


def _take_shape(contact: _Contact, event: TouchEvent, now: float) -> None:
    """Keep the largest contact kind the event's shape has shown (None: a fingertip) and its footprint."""
    if event.shape is None:
        return
    if _CONTACT_RANK.get(event.shape.contact, 0) > _CONTACT_RANK[contact.contact]:
        contact.contact = event.shape.contact
    if contact.contact == "hug" and contact.hug_since is None:
        contact.hug_since = now
    if event.shape.area_mm2 is not None:
        contact.area_mm2 = event.shape.area_mm2


def _centroid(strokes: tuple[tuple[tuple[float, float], ...], ...]) -> tuple[float, float]:
    points = [p for s in strokes for p in s]
    if not points:
        return 0.5, 0.5
    return sum(p[0] for p in points) / len(points), sum(p[1] for p in points) / len(points)
