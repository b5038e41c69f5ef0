"""A live rear-camera scene for the sim daemon and the partner's page: press, hover, release.

The daemon's sim camera asks for ``frame(t)`` at its own rate; the HTTP API
calls ``press`` and ``release`` when someone clicks on the partner page. The
fingertip does not teleport: a press from nothing comes down from 25 mm over
0.15 s (so the detector sees a hand arrive), a move while pressed slides, a
hover settles at ~3 mm and wobbles with tremor, a release lifts the hand away
over ~0.8 s. With ``[sim] autoplay`` an idle scene pats, holds, strokes and
hovers by itself now and then, so a sim daemon shows activity with nobody at
the page. Pure: time is always an argument, nothing reads a clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feelium.sim.config import SimConfig
from feelium.sim.hand import HandPose
from feelium.sim.hand_paths import HOVER_FLOOR_MM, Tremor, min_jerk
from feelium.sim.room import RoomLight
from feelium.skin.probe import ProbeLevels, light_at, probe_pattern
from feelium.sim.sessions import session_presets
from feelium.sim.scene import HEIGHT, ROI, WIDTH, Projected, SceneRenderer, SceneState, Session
from feelium.sim.shadow import ShadowParams

LIVE_HOVER_MM = 3.0
_ARRIVE_FROM_MM = 25.0
_ARRIVE_S = 0.15
_SLIDE_S = 0.06
_HOVER_SETTLE_S = 0.3
_LIFT_S = 0.35
_LEAVE_S = 0.8
_GONE_MM = 150.0


@dataclass(frozen=True)
class _Segment:
    """The fingertip moving from ``a`` to ``b`` (x px, y px, h mm) over [t0, t1] along minimum jerk."""

    t0: float
    a: tuple[float, float, float]
    t1: float
    b: tuple[float, float, float]

    def at(self, t: float) -> tuple[float, float, float]:
        s = min_jerk((t - self.t0) / max(self.t1 - self.t0, 1e-9))
        return tuple(p + (q - p) * s for p, q in zip(self.a, self.b))  # type: ignore[return-value]


@dataclass(frozen=True)
class _Event:
    t: float
    kind: str  # "press", "hover", "release"
    x: float = 0.0
    y: float = 0.0


class LiveRearScene:
    """The rear camera's view of a membrane that can be pressed at will (pure; time is an input)."""

    def __init__(
        self, config: SimConfig, *, width: int = WIDTH, height: int = HEIGHT, projected: Projected | None = None
    ) -> None:
        """``projected``: camera time to the projected light's factor (the projector's share of the membrane's
        light only; room light does not follow it), for a scene lit by what the projector shows; ``None``: the
        flat back-light (:meth:`project_probe` can light it with the projector's probe later). ``[sim] room_light``:
        a lit room's lamp through the membrane (:mod:`feelium.sim.room`)."""
        if width < 32 or height < 24:
            raise ValueError(f"live scene needs at least 32x24 pixels, got {width}x{height}")
        self.width, self.height = width, height
        sx, sy = width / WIDTH, height / HEIGHT
        self.roi = (round(ROI[0] * sx), round(ROI[1] * sy), round(ROI[2] * sx), round(ROI[3] * sy))
        base = session_presets(config.seed)[config.session]
        shadow = ShadowParams(**{**vars(base.shadow), "px_per_mm": base.shadow.px_per_mm * sx})
        self.session = Session(base.name, base.optics, shadow, base.sensor, base.membrane_seed)
        if (width, height) != (WIDTH, HEIGHT):
            self.session = _scaled_session(self.session, sx)
        self._config = config
        self._rng = np.random.default_rng([config.seed, 0x11FE])
        self._projected = projected
        room = RoomLight(level=config.room_light) if config.room_light > 0.0 else None
        self._renderer = SceneRenderer(
            self.session, self._rng, width=width, height=height, roi=self.roi, projected=self._light,
            projected_share_only=True, room_light=room,
        )  # fmt: skip
        self._tremor = Tremor.draw(self._rng, drift_mm=0.6)
        self._segment: _Segment | None = None  # None: no hand
        self._pressed = False
        self._touch_from = math.inf  # while pressed, the fingertip is on the membrane from this time
        self._gone_at = math.inf
        self._events: list[_Event] = []  # scheduled autoplay actions, in time order
        self._last_manual = -math.inf
        self._next_auto = config.autoplay_period_s
        self._auto_rng = np.random.default_rng([config.seed, 0xA070])
        self.autoplayed = 0

    def project_probe(self, levels: ProbeLevels, origin: float, latency_s: float) -> None:
        """Light the scene with the probe the projector lays (:mod:`feelium.skin.probe`): ``levels`` as the
        projector service publishes them on the daemon's clock (scene time + ``origin``), lit ``latency_s`` after
        they were shown, mixed over the camera's exposure as the touch side mixes them."""
        pattern = probe_pattern(self.width, self.height)
        exposure_s = self.session.sensor.exposure_s

        def probe(t: float) -> np.ndarray | None:
            level = levels.level(t + origin, exposure_s, latency_s)
            return None if level is None else light_at(level, pattern)

        self._projected = probe

    def _light(self, t: float) -> np.ndarray | None:
        return None if self._projected is None else self._projected(t)

    # ---- control --------------------------------------------------------------------------
    def press(self, x: float, y: float, t: float, *, hover: bool = False) -> None:
        """Put or move a fingertip at camera pixel (x, y) from time ``t`` (``hover``: ~3 mm above)."""
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(t)):
            raise ValueError(f"press needs finite x, y, t; got {x}, {y}, {t}")
        self._run_due(t)
        self._events.clear()  # a person takes over from autoplay
        self._last_manual = t
        self._apply(_Event(t, "hover" if hover else "press", float(x), float(y)))

    def release(self, t: float) -> None:
        """Lift the fingertip away from time ``t``."""
        if not math.isfinite(t):
            raise ValueError(f"release needs a finite t; got {t}")
        self._run_due(t)
        self._events.clear()
        self._last_manual = t
        self._apply(_Event(t, "release"))

    # ---- state ----------------------------------------------------------------------------
    def hand(self, t: float) -> HandPose | None:
        """The hand at time ``t`` (after running any autoplay due by then), or None."""
        self._advance(t)
        if self._segment is None or t >= self._gone_at:
            return None
        x, y, h = self._segment.at(t)
        if self._pressed and t >= self._touch_from:
            return HandPose(x, y, 0.0, pitch_deg=35.0)
        dx, dy, dh = self._tremor.offset(t)
        return HandPose(x + dx, y + dy, max(HOVER_FLOOR_MM, h + dh), pitch_deg=35.0)

    def touching(self, t: float) -> bool:
        hand = self.hand(t)
        return hand is not None and hand.pressed

    def frame(self, t: float) -> np.ndarray:
        """The rear camera's (H, W) uint8 frame at camera time ``t``."""
        hand = self.hand(t)
        return self._renderer.frame(t, SceneState(hands=(hand,) if hand is not None else ()))

    # ---- internals ------------------------------------------------------------------------
    def _position(self, t: float) -> tuple[float, float, float] | None:
        if self._segment is None or t >= self._gone_at:
            return None
        return self._segment.at(t)

    def _apply(self, event: _Event) -> None:
        t = event.t
        now = self._position(t)
        if event.kind == "release":
            if now is None:
                return
            x, y, h = now
            self._segment = _Segment(t, now, t + _LIFT_S, (x, y, 40.0))
            self._pressed = False
            self._touch_from = math.inf
            self._gone_at = t + _LEAVE_S
            return
        target_h = 0.0 if event.kind == "press" else LIVE_HOVER_MM
        pinned = event.kind == "press" and self._pressed and t >= self._touch_from
        if now is None:
            start = (event.x, event.y + 30.0, _ARRIVE_FROM_MM)
            self._segment = _Segment(t, start, t + _ARRIVE_S, (event.x, event.y, target_h))
        else:
            duration = _SLIDE_S if pinned else (_ARRIVE_S if event.kind == "press" else _HOVER_SETTLE_S)
            self._segment = _Segment(t, now, t + duration, (event.x, event.y, target_h))
        if event.kind == "press" and not pinned:
            self._touch_from = self._segment.t1  # lands when the descent ends
        elif event.kind == "hover":
            self._touch_from = math.inf
        self._pressed = event.kind == "press"
        self._gone_at = math.inf

    def _advance(self, t: float) -> None:
        """Run autoplay: schedule a new action when idle and apply the actions due by ``t``."""
        cfg = self._config
        if cfg.autoplay and not self._events and t >= self._next_auto and t - self._last_manual >= cfg.autoplay_idle_s:
            self._events = self._auto_action(t)
            self._next_auto = self._events[-1].t + cfg.autoplay_period_s * float(self._auto_rng.uniform(0.6, 1.4))
            self.autoplayed += 1
        self._run_due(t)

    def _run_due(self, t: float) -> None:
        while self._events and self._events[0].t <= t:
            self._apply(self._events.pop(0))

    def _auto_action(self, t: float) -> list[_Event]:
        """A pat, a hold, a stroke or a hover somewhere on the patch."""
        rng = self._auto_rng
        rx, ry, rw, rh = self.roi
        x, y = rx + rw * float(rng.uniform(0.15, 0.85)), ry + rh * float(rng.uniform(0.15, 0.85))
        kind = str(rng.choice(["pat", "hold", "stroke", "hover"]))
        if kind == "pat":
            events = [_Event(t, "press", x, y), _Event(t + _ARRIVE_S + float(rng.uniform(0.1, 0.25)), "release")]
        elif kind == "hold":
            events = [_Event(t, "press", x, y), _Event(t + _ARRIVE_S + float(rng.uniform(1.2, 2.5)), "release")]
        elif kind == "stroke":
            angle = float(rng.uniform(0, 2 * math.pi))
            length = float(rng.uniform(60, 160)) * self.width / WIDTH
            x1 = min(max(x + math.cos(angle) * length, rx + 10), rx + rw - 10)
            y1 = min(max(y + math.sin(angle) * length, ry + 10), ry + rh - 10)
            steps = 8
            events = [_Event(t, "press", x, y)]
            for i in range(1, steps + 1):
                s = i / steps
                events.append(_Event(t + _ARRIVE_S + 0.08 * i, "press", x + (x1 - x) * s, y + (y1 - y) * s))
            events.append(_Event(events[-1].t + 0.05, "release"))
        else:
            events = [_Event(t, "hover", x, y), _Event(t + float(rng.uniform(1.5, 3.0)), "release")]
        return events


def _scaled_session(session: Session, scale: float) -> Session:
    """The session's optics in a camera of another resolution (lengths in px scale with it)."""
    o = session.optics
    optics = type(o)(
        **{
            **vars(o),
            "throw_px": o.throw_px * scale,
            "center_dx": o.center_dx * scale,
            "center_dy": o.center_dy * scale,
            "hotspot_sigma": o.hotspot_sigma * scale,
            "hotspot_dx": o.hotspot_dx * scale,
            "hotspot_dy": o.hotspot_dy * scale,
            "seam_width_px": max(1.0, o.seam_width_px * scale),
            "banding_period_px": o.banding_period_px * scale,
        }
    )
    return Session(session.name, optics, session.shadow, session.sensor, session.membrane_seed)
