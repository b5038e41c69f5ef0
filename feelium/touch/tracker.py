"""From per-frame shadow decisions to touch events (down, move, up) with ids and kinds.

Shadows are associated frame to frame by the smallest total distance between
each track's *predicted* position (its last one moved on by its velocity) and
this frame's shadows, within ``match_distance_px`` (an exact assignment: there
are only a few contacts), so two simultaneous contacts keep their own ids even
when they come close, and a swipe that crosses a held touch comes out on its
own side. While the two shadows are one (the crossing itself), every contact
that is down and predicted on a shadow that is not only its own is seen at its
own last position, its prediction running on, rather than released or moved
to the merged centre: both ids survive. A touch is confirmed after
``down_frames`` consecutive touching frames and released after ``release_s`` of not touching (debouncing both ends).
A confirmed ``down`` carries the confirming frame's time (the event cannot be known sooner) but the position,
depth and area of the deepest frame since the gates passed: the frames after that one only had to stay under
the release hysteresis, and the shortest taps are already lifting then, their fingertip a few pixels off, while
a press still sinking in is better centred on its deeper frame (the fingertip's shadow in a lit room falls off
the pad until the skin is pressed). On
release the contact is classified: a swipe when its fingertip path (with a
jitter deadband) is long, else a hold when it lasted long, else a tap. Every
event also says what touched (:mod:`feelium.touch.shape`): a track keeps the
largest kind it showed while down, since a palm lands heel first and a hug grows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from feelium.events import ContactShape, TouchEvent, TouchKind
from feelium.touch.config import TouchConfig
from feelium.touch.gates import has_contact_edge, is_touching
from feelium.touch.rolling import RollingMin
from feelium.touch.shape import larger

EXACT_MAX_OBSERVATIONS = 6  # beyond this many shadows in a frame the assignment is greedy (2^n states)
VELOCITY_SMOOTHING = 0.5  # weight of the newest frame-to-frame velocity in a track's velocity
# A contact hidden in another's shadow stays down this long at most: a swipe crossing a held fingertip (two
# pads, ~25 mm, at >= 25 mm/s) is through in a second, while a finger lifted beside a palm must still release.
MERGED_MAX_S = 1.0


@dataclass(frozen=True)
class Observation:
    """One candidate shadow this frame, in camera pixels."""

    x: float
    y: float
    u: float
    v: float
    depth: float  # core depth
    area: int  # camera pixels
    edge: float  # steepest depth gradient near the fingertip, per camera px (contact edge)
    shape: ContactShape | None = None  # the footprint: what touched
    reach: float = 0.0  # half the footprint's longest axis, camera px
    # False when the shadow took none of the projector's own light where its share is known (a hand above the
    # membrane, :mod:`feelium.touch.roomshare`): it cannot land, so no gate raises it; a contact already held keeps
    # its release hysteresis (a tap's lifting frame still confirms it).
    projected: bool = True


@dataclass
class Track:
    """One shadow followed over frames; a contact while ``event_id`` is set."""

    last_seen_t: float
    obs: Observation
    anchor: float = 0.0
    landed_t: float | None = None  # start of the current run of frames with a contact edge
    landed_depths: RollingMin | None = None  # core depth since landing (None while not landed)
    seen: bool = True
    streak: int = 0
    event_id: int | None = None
    down_t: float = 0.0
    last_touch_t: float = 0.0
    release_t: float | None = None
    path_len: float = 0.0
    path_anchor: tuple[float, float] = (0.0, 0.0)
    reported: tuple[float, float] = (0.0, 0.0)
    touch_obs: Observation | None = None
    landing: Observation | None = None  # the deepest frame since the gates passed, while the onset is confirmed
    max_area: int = 0
    max_depth: float = 0.0
    velocity: tuple[float, float] = (0.0, 0.0)  # camera px per second, smoothed
    contact: ContactShape | None = None  # the footprint reported with events (largest kind while down)
    widest: Observation | None = None  # the observation of the widest footprint while down (for ``up``)

    def predicted(self, t: float) -> tuple[float, float]:
        """Where the track should be at ``t``: its last position moved on by its velocity."""
        dt = max(t - self.last_seen_t, 0.0)
        return self.obs.x + self.velocity[0] * dt, self.obs.y + self.velocity[1] * dt

    @property
    def down(self) -> bool:
        return self.event_id is not None


@dataclass(frozen=True)
class Contact:
    """A contact currently down, for overlays and the projector."""

    id: int
    x: float
    y: float
    u: float
    v: float
    depth: float
    area: int
    anchor: float
    since: float


@dataclass
class TrackerStep:
    events: list[TouchEvent] = field(default_factory=list)
    anchor: float = 0.0  # max anchoring score over shadows seen this frame
    protected: list[bool] = field(default_factory=list)  # per observation: under a contact or anchored


class Tracker:
    """Segments per-frame decisions into events. Pure: time comes in with each frame."""

    def __init__(self, config: TouchConfig) -> None:
        self.config = config
        self.tracks: list[Track] = []
        self.next_id = 1

    def reset(self) -> None:
        self.tracks = []

    def step(self, t: float, observations: list[Observation], *, settled: bool = True) -> TrackerStep:
        """Advance every track by one frame.

        ``settled=False`` (the projector's response to projected light is not learned yet, so the compensation
        is only a guess): no new touch is raised and no shadow lands (its anchoring window starts again once
        settled), while touches already down stay down as long as their shadow is seen.
        """
        cfg = self.config
        out = TrackerStep()
        if not observations and not self.tracks:
            return out  # nothing seen and nothing to follow (most frames): what every step below would leave
        matched = self._associate(t, observations)
        shared = self._shared(t, observations, matched)
        for track in self.tracks:
            track.seen = False
        new_tracks = []
        for index, obs in enumerate(observations):
            track = matched.get(index)
            if track is None:
                track = Track(last_seen_t=t, obs=obs)
                new_tracks.append(track)
            elif id(track) in shared:
                continue
            elif t > track.last_seen_t:
                vx, vy = (obs.x - track.obs.x) / (t - track.last_seen_t), (obs.y - track.obs.y) / (t - track.last_seen_t)
                a = VELOCITY_SMOOTHING
                track.velocity = (a * vx + (1 - a) * track.velocity[0], a * vy + (1 - a) * track.velocity[1])
            track.obs = obs
            track.seen = True
            track.last_seen_t = t
        for track, obs in shared.values():
            # Seen at its own last position; its last sighting and velocity stay, so its prediction runs on.
            track.obs = obs
            track.seen = True
        self.tracks.extend(new_tracks)

        survivors = []
        for track in self.tracks:
            depth = track.obs.depth if track.seen else 0.0
            if not settled and not track.down:
                track.landed_t, track.landed_depths, track.anchor, track.streak = None, None, 0.0, 0
                if t - track.last_seen_t <= cfg.release_s:
                    survivors.append(track)
                continue
            landed_s = self._land(track, t, depth)
            if track.seen:
                out.anchor = max(out.anchor, track.anchor)
            # Once a gate has passed, the next frames only need the release hysteresis to confirm the onset:
            # the shortest taps are lifting again by their second frame at 15 fps, and a one-frame flicker
            # (nothing the frame after) is still debounced.
            held = track.down or track.streak > 0
            touching = is_touching(
                cfg,
                down=held,
                seen=track.seen,
                landed_s=landed_s,
                core_depth=depth,
                edge=track.obs.edge,
                anchor=track.anchor,
            )
            if not settled:
                touching = track.seen
            self._advance(track, t, touching, out.events)
            if track.down or t - track.last_seen_t <= cfg.release_s:
                survivors.append(track)
        self.tracks = survivors
        by_obs = {id(track.obs): track for track in survivors if track.seen}
        for obs in observations:
            track = by_obs.get(id(obs))
            out.protected.append(
                track is not None and (track.down or track.streak > 0 or track.anchor >= cfg.anchor_threshold)
            )
        return out

    def finish(self, t: float) -> list[TouchEvent]:
        """Release every contact still down (end of a recording) at time ``t``."""
        events = []
        for track in self.tracks:
            if track.down:
                track.release_t = track.release_t if track.release_t is not None else t
                events.append(self._release(track))
        self.tracks = []
        return events

    def contacts(self) -> list[Contact]:
        out = []
        for track in self.tracks:
            if track.down and track.touch_obs is not None:
                o = track.touch_obs
                out.append(Contact(track.event_id or 0, o.x, o.y, o.u, o.v, o.depth, o.area, track.anchor, track.down_t))
        return out

    # -- internals -------------------------------------------------------------------------

    def _land(self, track: Track, t: float, depth: float) -> float | None:
        """Update the track's landing and anchoring score; seconds since it landed, None when not landed.

        The rolling minimum restarts at each landing, so the score measures how
        the shadow held since it reached the membrane, not the approach before.
        """
        if not (track.seen and track.obs.projected and has_contact_edge(self.config, track.obs.edge)):
            track.landed_t, track.landed_depths, track.anchor = None, None, 0.0
            return None
        if track.landed_t is None or track.landed_depths is None:
            track.landed_t, track.landed_depths = t, RollingMin(self.config.anchor_window_s)
        track.anchor = track.landed_depths.push(t, depth)
        return t - track.landed_t

    def _associate(self, t: float, observations: list[Observation]) -> dict[int, Track]:
        """This frame's shadows matched to tracks: the smallest total distance from predicted positions.

        Each pair within ``match_distance_px`` costs its distance minus twice that
        limit (so a match always beats leaving a track and a shadow both unmatched);
        the exact minimum is found by dynamic programming over the set of used
        shadows, greedy on distance beyond :data:`EXACT_MAX_OBSERVATIONS`.
        """
        limit = self.config.match_distance_px
        predicted = [track.predicted(t) for track in self.tracks]
        near: list[list[tuple[float, int]]] = []
        for px, py in predicted:
            row = [(math.hypot(o.x - px, o.y - py), oi) for oi, o in enumerate(observations)]
            near.append([(d, oi) for d, oi in row if d <= limit])
        if len(observations) > EXACT_MAX_OBSERVATIONS:
            return self._greedy(near)
        best: dict[int, tuple[float, tuple[int, ...]]] = {0: (0.0, ())}
        for row in near:
            step: dict[int, tuple[float, tuple[int, ...]]] = {}
            for used, (cost, chosen) in best.items():
                options = [(cost, used, chosen + (-1,))]
                options += [(cost + d - 2 * limit, used | 1 << oi, chosen + (oi,)) for d, oi in row if not used >> oi & 1]
                for c, key, pick in options:
                    if key not in step or c < step[key][0]:
                        step[key] = (c, pick)
            best = step
        _, chosen = min(best.values(), key=lambda item: item[0])
        return {oi: self.tracks[ti] for ti, oi in enumerate(chosen) if oi >= 0}

    def _greedy(self, near: list[list[tuple[float, int]]]) -> dict[int, Track]:
        pairs = sorted((d, ti, oi) for ti, row in enumerate(near) for d, oi in row)
        used_t: set[int] = set()
        matched: dict[int, Track] = {}
        for _, ti, oi in pairs:
            if ti in used_t or oi in matched:
                continue
            used_t.add(ti)
            matched[oi] = self.tracks[ti]
        return matched

    def _shared(
        self, t: float, observations: list[Observation], matched: dict[int, Track]
    ) -> dict[int, tuple[Track, Observation]]:
        """Contacts that are down and predicted on a shadow that is not (only) theirs: two shadows that touch while
        crossing, for at most :data:`MERGED_MAX_S`.

        Each such contact (by ``id``) is seen at its own last position with that shadow's depth and edge, the one
        the shadow was assigned to included: the merged shadow's centre is neither's fingertip.
        """
        out: dict[int, tuple[Track, Observation]] = {}
        for index, obs in enumerate(observations):
            involved = []
            for track in self.tracks:
                if not track.down or t - track.last_seen_t > MERGED_MAX_S or id(track) in out:
                    continue
                px, py = track.predicted(t)
                if math.hypot(obs.x - px, obs.y - py) <= obs.reach + self.config.path_deadband_px:
                    involved.append(track)
            if len(involved) >= 2 or (len(involved) == 1 and matched.get(index) is not involved[0]):
                for track in involved:
                    own = track.obs
                    out[id(track)] = (track, replace(obs, x=own.x, y=own.y, u=own.u, v=own.v, shape=own.shape, reach=own.reach))
        return out

    def _advance(self, track: Track, t: float, touching: bool, events: list[TouchEvent]) -> None:
        cfg = self.config
        if not track.down:
            track.streak = track.streak + 1 if touching else 0
            if track.streak == 1 or (touching and track.landing is not None and track.obs.depth > track.landing.depth):
                track.landing = track.obs
            if touching and track.streak >= cfg.down_frames:
                landed = track.landing or track.obs
                track.landing = None
                track.event_id = self.next_id
                self.next_id += 1
                track.down_t = track.last_touch_t = t
                track.release_t = None
                track.path_len = 0.0
                track.path_anchor = track.reported = (landed.x, landed.y)
                track.touch_obs = track.widest = landed
                track.max_area = landed.area
                track.max_depth = landed.depth
                events.append(self._event(track, "down", t, None))
                # This frame is the contact's too: its footprint and path count from the landing point on, the
                # move it may have made is reported with the next frame's (an event per phase per frame).
                self._follow(track, track.obs)
            return
        if touching:
            track.last_touch_t = t
            track.release_t = None
            if self._follow(track, track.obs):
                track.reported = (track.obs.x, track.obs.y)
                events.append(self._event(track, "move", t, self._kind_so_far(track, t)))
            return
        if track.release_t is None:
            track.release_t = t
        if t - track.last_touch_t >= cfg.release_s:
            events.append(self._release(track))

    def _follow(self, track: Track, obs: Observation) -> bool:
        """Fold a touching frame into a contact that is down; True when it moved far enough to report."""
        cfg = self.config
        track.touch_obs = obs
        track.max_area = max(track.max_area, obs.area)
        track.max_depth = max(track.max_depth, obs.depth)
        if track.widest is None or obs.reach > track.widest.reach:
            track.widest = obs
        step = path_step(track.path_anchor, (obs.x, obs.y), cfg.path_deadband_px)
        if step is not None:
            track.path_len += step
            track.path_anchor = (obs.x, obs.y)
        rx, ry = track.reported
        return math.hypot(obs.x - rx, obs.y - ry) >= cfg.move_min_px

    def _release(self, track: Track) -> TouchEvent:
        assert track.release_t is not None
        kind = self._final_kind(track, track.release_t)
        event = self._event(track, "up", track.release_t, kind)
        track.event_id = None
        track.streak = 0
        track.touch_obs = None
        track.contact = track.widest = None
        return event

    def _kind_so_far(self, track: Track, t: float) -> TouchKind | None:
        return kind_so_far(t - track.down_t, track.path_len, self.config)

    def _final_kind(self, track: Track, end_t: float) -> TouchKind:
        return self._kind_so_far(track, end_t) or "tap"

    def _event(self, track: Track, phase: str, t: float, kind: TouchKind | None) -> TouchEvent:
        obs = track.touch_obs or track.obs
        # Every event reports the current footprint, ``up`` the widest (as ``area`` its largest), with the largest
        # kind seen while down.
        shown = track.widest if phase == "up" and track.widest is not None else obs
        if shown.shape is not None:
            what = shown.shape.contact if track.contact is None else larger(track.contact.contact, shown.shape.contact)
            track.contact = replace(shown.shape, contact=what)
        return TouchEvent(
            id=track.event_id or 0,
            phase=phase,  # type: ignore[arg-type]
            kind=kind,
            t=t,
            x=obs.x,
            y=obs.y,
            u=obs.u,
            v=obs.v,
            depth=obs.depth,
            area=obs.area if phase != "up" else track.max_area,
            anchor=track.anchor,
            shape=track.contact,
        )


def path_step(anchor: tuple[float, float], point: tuple[float, float], deadband_px: float) -> float | None:
    """What a fingertip moving from ``anchor`` (where its path last grew) to ``point`` adds to its path: the
    distance, or None within the jitter deadband (the anchor then stays). Shared with the labelling of simulated
    scenes (:mod:`feelium.lab.sim.take_multitouch`), so a true path is measured as the tracker measures one."""
    step = math.hypot(point[0] - anchor[0], point[1] - anchor[1])
    return step if step >= deadband_px else None


def kind_so_far(duration_s: float, path_px: float, config: TouchConfig) -> TouchKind | None:
    """The kind of a contact down ``duration_s`` with a fingertip path of ``path_px``: a swipe when the path is long,
    else a hold when it lasted long, else not known yet (a tap, once released)."""
    if path_px >= config.swipe_min_path_px:
        return "swipe"
    if duration_s >= config.hold_min_s:
        return "hold"
    return None
