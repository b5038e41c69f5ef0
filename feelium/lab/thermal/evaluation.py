"""How well presence works, on simulated clips: detection rate, false alarms per hour, latency.

Approach clips have one body (a hand reaching to the skin, or a partner
stepping up) walking in from about 2 m, staying, and walking out; empty clips
hold only the room (noise, chess pattern, ambient drift). Ground truth is
distance: a body is *near* while within ``near_mm`` of the membrane. An
approach clip is detected when an ``approach`` event falls between the body
starting to move in and it leaving the near zone; its latency is that event's
time minus the moment it came near (negative: noticed before it was near).
Leave latency is the ``leave`` event's time minus the moment the body left the
near zone. Every ``approach`` in an empty clip, or before a body started
moving, is a false alarm.

Frames come straight from the scene renderer at the sub-page rate (the
decoder's own accuracy is tested against the vendor and the simulated
sensor separately), so an hour of empty room evaluates in seconds. With
``through_driver`` each frame instead goes the daemon's whole way: the
simulated sensor turns the scene into raw words (ADC rounding included), the
real transport, driver and decoder read them back, about 4 ms a sub-page.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from feelium.events import PresenceEvent
from feelium.sim.thermal import ThermalSceneRenderer, Visit
from feelium.thermal import registers as reg
from feelium.thermal.config import PresenceConfig
from feelium.thermal.decoder import FrameAssembler
from feelium.thermal.driver import Mlx90640Driver
from feelium.thermal.sim_device import SimMlx90640, VirtualClock
from feelium.thermal.presence import PresenceDetector
from feelium.thermal.transport import SMBus2Transport


@dataclass(frozen=True)
class Clip:
    """One simulated clip: its visits (none for an empty room), length and room."""

    name: str
    duration_s: float
    visits: tuple[Visit, ...]
    ambient_c: float
    seed: int


ROOM_C = (19.0, 26.0)  # an ordinary indoor room


def approach_clip(rng: np.random.Generator, index: int, room_c: tuple[float, float] = ROOM_C) -> Clip:
    """A hand reaching to touch (60 %) or a partner stepping up (40 %), at a random place and pace."""
    hand = rng.random() < 0.6
    walk = float(rng.uniform(1.5, 4.0))
    stay = float(rng.uniform(2.0, 8.0))
    start = float(rng.uniform(8.0, 12.0))
    visit = Visit(
        t_start=start,
        walk_s=walk,
        stay_s=stay,
        u=float(rng.uniform(0.2, 0.8)),
        v=float(rng.uniform(0.2, 0.8)),
        radius=float(rng.uniform(0.09, 0.15) if hand else rng.uniform(0.35, 0.6)),
        skin_c=float(rng.uniform(31.5, 34.5) if hand else rng.uniform(28.5, 32.0)),
        far_mm=2000.0,
        near_mm=float(rng.uniform(0.0, 20.0) if hand else rng.uniform(150.0, 400.0)),
    )
    ambient = float(rng.uniform(*room_c))
    return Clip(f"{'hand' if hand else 'partner'}-{index:03d}", visit.t_end + 10.0, (visit,), ambient, int(rng.integers(1 << 31)))


def empty_clip(rng: np.random.Generator, index: int, duration_s: float, room_c: tuple[float, float] = ROOM_C) -> Clip:
    return Clip(f"empty-{index:03d}", duration_s, (), float(rng.uniform(*room_c)), int(rng.integers(1 << 31)))


def run_clip(clip: Clip, config: PresenceConfig, fps: float, through_driver: bool = False) -> list[PresenceEvent]:
    """Render the clip at ``fps`` sub-pages a second and feed the detector; its events."""
    renderer = ThermalSceneRenderer(np.random.default_rng(clip.seed), clip.ambient_c, fps=fps / 2)
    detector = PresenceDetector(config)

    def scene(t: float) -> np.ndarray:
        return renderer.frame(t, [b for b in (v.body(t) for v in clip.visits) if b is not None])

    events: list[PresenceEvent] = []
    if not through_driver:
        for i in range(int(clip.duration_s * fps)):
            events.extend(detector.step(i / fps, scene(i / fps)))
        return events
    clock = VirtualClock()
    sensor = SimMlx90640(scene, clock=clock, sleep=clock.sleep, rng=np.random.default_rng(clip.seed + 1))
    driver = Mlx90640Driver(SMBus2Transport(sensor.bus()), reg.ControlSettings(fps, 18, "chess"))
    assembler = FrameAssembler(driver.start(), emissivity=1.0)
    while clock() < clip.duration_s:
        clock.sleep(1.0 / fps)
        words = driver.poll()
        image = None if words is None else assembler.add(words)
        if image is not None and assembler.complete:
            events.extend(detector.step(clock(), image))
    return events


def _stats(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    a = np.asarray(values) * 1000.0
    return {"median": round(float(np.median(a)), 1), "p95": round(float(np.percentile(a, 95)), 1),
            "min": round(float(a.min()), 1), "max": round(float(a.max()), 1)}


def evaluate_presence(
    *,
    approach: int = 40,
    empty: int = 6,
    empty_s: float = 600.0,
    seed: int = 0,
    config: PresenceConfig | None = None,
    fps: float = 8.0,
    near_mm: float = 500.0,
    room_c: tuple[float, float] = ROOM_C,
    through_driver: bool = False,
) -> dict[str, Any]:
    """Run the clips and score them (see the module docstring); a JSON-ready report.

    ``room_c``: the range room temperatures are drawn from; a room near skin
    temperature leaves a body little contrast, which is where presence fails.
    """
    if not room_c[0] <= room_c[1]:
        raise ValueError(f"room_c must be (low, high), got {room_c}")
    config = config if config is not None else PresenceConfig()
    rng = np.random.default_rng(seed)
    detected = 0
    evaluated = 0
    false_alarms = 0
    latencies: list[float] = []
    leave_latencies: list[float] = []
    detect_mm: list[float] = []
    missed: list[str] = []
    by_kind: dict[str, dict[str, int]] = {}
    for i in range(approach):
        clip = approach_clip(rng, i, room_c)
        visit = clip.visits[0]
        near = visit.near_interval(near_mm)
        if near is None:
            continue
        evaluated += 1
        kind = clip.name.split("-")[0]
        counts = by_kind.setdefault(kind, {"n": 0, "detected": 0})
        counts["n"] += 1
        events = run_clip(clip, config, fps, through_driver)
        approaches = [e for e in events if e.phase == "approach"]
        false_alarms += sum(1 for e in approaches if e.t < visit.t_start)
        hits = [e for e in approaches if visit.t_start <= e.t <= near[1]]
        if hits:
            detected += 1
            counts["detected"] += 1
            latencies.append(hits[0].t - near[0])
            detect_mm.append(float(visit.distance(hits[0].t) or 0.0))
            leaves = [e for e in events if e.phase == "leave" and e.t >= hits[0].t]
            if leaves:
                leave_latencies.append(leaves[0].t - near[1])
        else:
            missed.append(clip.name)
    empty_hours = 0.0
    empty_alarms = 0
    for i in range(empty):
        clip = empty_clip(rng, i, empty_s, room_c)
        empty_alarms += sum(1 for e in run_clip(clip, config, fps, through_driver) if e.phase == "approach")
        empty_hours += empty_s / 3600.0
    return {
        "clips": {"approach": evaluated, "empty": empty, "empty_hours": round(empty_hours, 3)},
        "near_mm": near_mm,
        "room_c": list(room_c),
        "through_driver": through_driver,
        "fps": fps,
        "detection_rate": round(detected / evaluated, 4) if evaluated else None,
        "by_kind": by_kind,
        "missed": missed,
        "false_alarms_per_hour": round(empty_alarms / empty_hours, 3) if empty_hours else None,
        "false_alarms_in_approach_clips": false_alarms,
        "approach_latency_ms": _stats(latencies),
        "leave_latency_ms": _stats(leave_latencies),
        "detected_at_mm": None if not detect_mm else {
            "median": round(float(np.median(detect_mm)), 1), "max": round(float(np.max(detect_mm)), 1)
        },
        "seed": seed,
    }


__all__ = ["ROOM_C", "Clip", "approach_clip", "empty_clip", "evaluate_presence", "run_clip"]
