"""The six exchanges as pure rules: touch events and wearer actions in, events, answers and motions out."""

from __future__ import annotations

import math

import pytest

from feelium.events import InteractionEvent, WearerAction
from feelium.interactions.config import InteractionsConfig
from feelium.interactions.engine import InteractionEngine
from tests.interactions.touches import at_uv, event, hold, shape, swipe, tap

CONFIG = InteractionsConfig()


class Driver:
    """Feeds timed inputs to an engine with ticks every 1/30 s, collecting everything it produced."""

    def __init__(self, config: InteractionsConfig = CONFIG) -> None:
        self.engine = InteractionEngine(config)
        self.events: list[InteractionEvent] = []
        self.motions = []
        self.now = 0.0

    def run_until(self, t: float) -> None:
        while self.now + 1 / 30 <= t:
            self.now += 1 / 30
            step = self.engine.tick(self.now)
            self.events += step.events
            self.motions += step.motions

    def feed(self, items) -> None:
        for item in sorted(items, key=lambda i: i.t):
            self.run_until(item.t)
            if isinstance(item, WearerAction):
                self.engine.action(item, item.t)
            else:
                self.engine.touch(item, item.t)
        self.run_until(self.now + 1 / 30)

    def names(self) -> list[tuple[str, str]]:
        return [(e.name, e.phase) for e in self.events]


def test_greeting_pat_counts_taps_and_answers_with_ripple_and_warm_pulse():
    d = Driver()
    x, y = at_uv(0.5, 0.2)
    d.feed(tap(1, 1.0, x, y) + tap(2, 1.8, x + 5, y))
    pats = [e for e in d.events if e.name == "greeting_pat"]
    assert [e.detail["taps"] for e in pats] == [1, 2]
    assert pats[0].region == "head" and pats[0].x == pytest.approx(x)
    kinds = {a.kind for a in d.engine.answers(d.now)}
    assert {"ripple", "warm_pulse"} <= kinds
    pulse = [a for a in d.engine.answers(d.now) if a.kind == "warm_pulse"][-1]
    assert (pulse.u, pulse.v) == pytest.approx((0.5 + 5 / 512, 0.2))


def test_a_tap_on_the_body_is_not_a_pat():
    d = Driver()
    d.feed(tap(1, 1.0, *at_uv(0.5, 0.45)))
    assert d.names() == []


def test_peck_blooms_a_heart_on_the_cheek_and_the_wearers_heart_returns_there():
    d = Driver()
    d.feed(tap(1, 1.0, *at_uv(0.27, 0.58)))
    assert d.names() == [("peck", "bloom")]
    assert d.events[0].region == "cheek_left"
    d.feed([WearerAction("heart", 2.0)])
    assert d.names()[-1] == ("peck", "returned") and d.events[-1].region == "cheek_left"
    hearts = [a for a in d.engine.answers(d.now) if a.kind == "heart"]
    assert [h.detail["from"] for h in hearts] == ["partner", "wearer"]
    assert (hearts[1].u, hearts[1].v) == pytest.approx((0.27, 0.58))


def test_palm_to_palm_needs_both_sides_then_merges_and_ends():
    d = Driver()
    x, y = at_uv(0.6, 0.75)
    d.feed([WearerAction("palm_raise", 0.5)])
    assert d.names() == [("palm_to_palm", "wearer")]
    events = hold(1, 1.0, x, y, duration=2.0, area=4000, contact=shape("palm", 9000.0))
    d.feed(events[:-1])
    assert d.names()[1:] == [("palm_to_palm", "partner"), ("palm_to_palm", "merge")]
    partner = next(e for e in d.events if e.phase == "partner")
    assert partner.t == pytest.approx(1.0 + CONFIG.palm_hold_s, abs=0.05)
    wearer_glow = next(a for a in d.engine.answers(d.now) if a.kind == "palm_glow" and a.detail["side"] == "wearer")
    assert wearer_glow.detail["merged"] and (wearer_glow.u, wearer_glow.v) == pytest.approx((0.6, 0.75))
    d.feed(events[-1:])
    assert d.names()[-1] == ("palm_to_palm", "end")
    glows = [a for a in d.engine.answers(d.now) if a.kind == "palm_glow" and a.detail["side"] == "wearer"]
    assert (glows[0].u, glows[0].v) == pytest.approx(CONFIG.palm_zone[:2])  # the wearer's palm waits in its zone again


def test_a_fingertip_hold_is_not_a_palm():
    d = Driver()
    d.feed([WearerAction("palm_raise", 0.5)] + hold(1, 1.0, *at_uv(0.6, 0.75), duration=2.0, area=400, contact=shape("finger", 240.0)))
    assert ("palm_to_palm", "partner") not in d.names()


@pytest.mark.parametrize("area_px", [40, 4000, 400_000])
def test_palm_and_hug_follow_the_contact_kind_at_any_camera_scale(area_px):
    """The camera's pixel count of a footprint depends on its resolution and lens; the contact kind does not."""
    d = Driver()
    d.feed(hold(1, 1.0, *at_uv(0.6, 0.75), duration=2.0, area=area_px, contact=shape("palm", 9000.0)))
    assert d.names() == [("palm_to_palm", "partner"), ("palm_to_palm", "end")]
    assert d.events[0].detail["contact_area_mm2"] == 9000.0
    d = Driver()
    d.feed(hold(1, 1.0, *at_uv(0.5, 0.5), duration=3.0, area=area_px, contact=shape("hug", 25000.0)))
    assert d.names() == [("hug", "start"), ("hug", "end")]
    d = Driver()
    d.feed(hold(1, 1.0, *at_uv(0.5, 0.5), duration=3.0, area=area_px))  # no shape (an older stream): a fingertip
    assert d.names() == []


def test_a_palm_landing_heel_first_becomes_a_palm_and_a_sliding_palm_does_not_draw():
    d = Driver()
    x, y = at_uv(0.6, 0.75)
    heel = hold(1, 1.0, x, y, duration=0.3, area=900, contact=shape("finger", 300.0))[:-1]
    flat = hold(1, 1.3, x, y, duration=1.5, area=4000, contact=shape("palm", 9000.0))[1:]
    d.feed(heel + flat)
    assert ("palm_to_palm", "partner") in d.names()
    d = Driver()
    d.feed(swipe(2, 1.0, [at_uv(0.3 + 0.03 * k, 0.5) for k in range(12)], contact=shape("palm", 9000.0)))
    assert not [n for n in d.names() if n[0] == "drawing"]


def test_drawing_strokes_stream_live_and_a_correct_guess_ignites():
    d = Driver()
    pts = [at_uv(0.3 + 0.02 * k, 0.5 + 0.01 * k) for k in range(12)]
    d.feed(swipe(1, 1.0, pts))
    names = d.names()
    assert names[0] == ("drawing", "start") and ("drawing", "stroke_end") in names
    strokes = [e for e in d.events if e.phase == "stroke"]
    sent = [p for e in strokes for p in e.detail["points"]]
    assert len(sent) >= 10 and sent[-1] == pytest.approx([0.52, 0.61], abs=1e-3)
    stroke = next(a for a in d.engine.answers(d.now) if a.kind == "stroke")
    assert (stroke.detail["round"], stroke.detail["stroke"]) == (1, 1)  # the projector's stroke layer keys on these
    prompt = next(a for a in d.engine.answers(d.now) if a.kind == "prompt")
    word = prompt.detail["text"].removeprefix("draw: ")
    d.feed([WearerAction("guess", 3.0, {"word": "definitely wrong"}), WearerAction("guess", 3.5, {"word": word.upper() + "S"})])
    assert d.names()[-2:] == [("drawing", "wrong_guess"), ("drawing", "ignite")]
    assert d.events[-1].detail["word"] == word
    ignite = next(a for a in d.engine.answers(d.now) if a.kind == "ignite")
    assert len(ignite.detail["strokes"]) == 1
    d.run_until(3.5 + CONFIG.ignite_s + 0.1)
    assert d.names()[-1] == ("drawing", "end")
    assert not any(a.kind in ("stroke", "ignite") for a in d.engine.answers(d.now))


def test_the_secret_word_is_reproducible_per_seed_and_round():
    words = []
    for _ in range(2):
        d = Driver()
        d.feed(swipe(1, 1.0, [at_uv(0.3 + 0.03 * k, 0.5) for k in range(8)]))
        words.append(next(a for a in d.engine.answers(d.now) if a.kind == "prompt").detail["text"])
    assert words[0] == words[1]


def test_lean_in_hug_breathes_the_whole_skin_until_release():
    d = Driver()
    d.feed(hold(1, 1.0, *at_uv(0.5, 0.5), duration=3.0, area=20000, contact=shape("hug", 25000.0)))
    assert d.names() == [("hug", "start"), ("hug", "end")]
    start = d.events[0]
    assert start.t == pytest.approx(1.0 + CONFIG.hug_hold_s, abs=0.05)
    breathing = [a for a in d.engine.answers(d.now) if a.kind == "breathing"]
    assert breathing and math.isfinite(breathing[0].until)  # fading out after the release


def test_short_large_contact_is_not_a_hug():
    d = Driver()
    d.feed(hold(1, 1.0, *at_uv(0.5, 0.5), duration=0.8, area=20000, contact=shape("hug", 25000.0)))
    assert ("hug", "start") not in d.names()


def test_shimmer_invites_drifts_closer_and_a_touch_accepts_with_a_bounce():
    d = Driver()
    d.feed([WearerAction("shimmer", 1.0)])
    assert d.names() == [("invite", "shimmer")]
    assert [(m.name, m.reason) for m in d.motions] == [("forward", "drift_closer")]
    d.feed(tap(1, 2.0, *at_uv(0.5, 0.5)))
    d.run_until(3.0)
    assert ("invite", "accepted") in d.names()
    assert [m.name for m in d.motions] == ["forward", "up", "down"]
    assert d.motions[2].at - d.motions[1].at == pytest.approx(CONFIG.bounce_hold_s)
    assert not any(a.kind == "shimmer" and a.alive(d.now) for a in d.engine.answers(d.now))


def test_a_touch_after_the_shimmer_ended_is_not_an_acceptance():
    d = Driver()
    d.feed([WearerAction("shimmer", 1.0)])
    d.feed(tap(1, 1.0 + CONFIG.shimmer_s + 0.5, *at_uv(0.5, 0.5)))
    assert ("invite", "accepted") not in d.names()


def test_stale_motion_replies_are_dropped_not_sent_late():
    engine = InteractionEngine(CONFIG)
    engine.action(WearerAction("shimmer", 1.0), 1.0)
    step = engine.tick(2.0)
    assert step.motions == () and engine.counts["motions_dropped"] == 1


def test_events_without_coordinates_are_counted_and_ignored():
    engine = InteractionEngine(CONFIG)
    engine.touch(event(1, "down", 1.0, float("nan"), float("nan")), 1.0)
    assert engine.counts["ignored"] == 1 and engine.tick(1.1).events == ()


def test_bad_region_config_is_rejected_with_its_name():
    with pytest.raises(ValueError, match="interactions.head"):
        InteractionEngine(InteractionsConfig(head=(0.5, 0.2, 0.3)))


def test_a_drawing_that_never_ends_keeps_only_its_latest_strokes_and_points():
    """A round kept alive by strokes and wrong guesses must not pile strokes up for the projector to draw."""
    from feelium.interactions.engine import MAX_STROKE_POINTS, MAX_STROKES

    d = Driver()
    items = []
    for n in range(MAX_STROKES + 20):
        t = 1.0 + 1.0 * n
        items += swipe(n + 1, t, [at_uv(0.3 + 0.02 * k, 0.5) for k in range(6)])
        if n % 5 == 4:
            items.append(WearerAction("guess", t + 0.6, {"word": "definitely wrong"}))
    d.feed(items)
    strokes = [a for a in d.engine.answers(d.now) if a.kind == "stroke"]
    assert len(strokes) == MAX_STROKES  # the round is still on (no idle gap), its oldest strokes gone
    assert ("drawing", "end") not in d.names()

    long = [at_uv(0.1 + 0.8 * (k % 100) / 100, 0.3 + 0.3 * (k // 100) / 5) for k in range(2 * MAX_STROKE_POINTS + 10)]
    d.feed(swipe(999, d.now + 1.0, long, step=0.02))
    assert all(len(a.detail["points"]) <= MAX_STROKE_POINTS + 1 for a in d.engine.answers(d.now) if a.kind == "stroke")
    assert len([a for a in d.engine.answers(d.now) if a.kind == "stroke"]) == MAX_STROKES
