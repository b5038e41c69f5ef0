"""Recovery of full sensitivity after a light switch, measured on a recording (issue 17, point 2), for ``eval``.

The lab experiment (:mod:`feelium.lab.touch.litroom`) measures it on a hand-free twin of each trial against a twin
in the final light held steady, both rendered for it. A recording has neither: it has its own frames, hands and
all. So the same measure (:func:`~feelium.lab.touch.litroom.sensed`: a copy of the pipeline handed each frame with
a known fingertip's shadow pressed at each of five places, reading its core depth; :func:`~feelium.lab.touch.litroom.
off_steady`: recovered from the first frame after which every place is found and reads within
:data:`~feelium.lab.touch.litroom.SENSE_TOLERANCE` of steady light; :func:`~feelium.lab.touch.litroom.recovered`)
is read on the recording's own frames, with two differences the recording forces:

- the *steady light* is the recording's frames from the switch on, read by a pipeline started there: it has only
  ever seen the final light, as the lab's steady twin has (a relative depth is a ratio, so a pipeline whose
  reference is right reads the known contact alike in any steady light; the switch's ramp and the auto-exposure's
  lag are in its first frames, which the median over its readings outvotes);
- only **hand-free** recordings are measured (the spec's ``empty`` label): a hand near a place reads as another
  depth in any light, and a pipeline's reference after a hover or a hold differs from one that never saw it, so on a
  trial with hands the measure would read the hand (measured: a hold of seed 31's switch-off put its place 0.05-0.08
  off for the rest of the trial, after the hand had gone). A recording with a switch and a hand is counted as not
  measurable, not scored.

When a switch happened is not among the spec's labels: a recording says so with the optional
``light_switches`` of ``labels.json`` (seconds on the camera clock, docs/recording-format.md), which ``feelium
simulate condition litroom`` writes and a person labelling a real take would write. A synthetic recording written
before that key existed still has its room's steps in ``meta.generator.room`` (the simulator's record, not a
label), read as a fallback. Nothing is detected from the frames: a real recording with no label is not measured.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from feelium.lab.touch import litroom
from feelium.lab.touch.replay import new_pipeline
from feelium.recording import Recording
from feelium.touch.config import TouchConfig

GOAL_S = 1.0  # issue 17, point 2: "recovery of full sensitivity within 1 s after a switch"

Light = Callable[[float], dict[str, Any]]


@dataclass(frozen=True)
class Switches:
    """When the room's light was switched in a recording, and where that was read from."""

    times: tuple[float, ...]
    source: str | None  # "label" (labels.json), "generator" (meta.generator.room of a synthetic take) or None


def switches_of(recording: Recording) -> Switches:
    """The recording's light switches: its labels' ``light_switches`` first, else its generator's room steps."""
    labels = recording.labels
    if labels is not None and labels.light_switches:
        return Switches(tuple(labels.light_switches), "label")
    generator = recording.meta.raw.get("generator")
    room = generator.get("room") if isinstance(generator, dict) else None
    steps = room.get("steps") if isinstance(room, dict) else None
    if isinstance(steps, list) and steps:
        try:
            return Switches(tuple(float(step[0]) for step in steps), "generator")
        except (TypeError, ValueError, IndexError):
            pass
    return Switches((), None)


def _frames(recording: Recording, start: float, end: float) -> Iterator[tuple[float, np.ndarray]]:
    for t, frame in recording.frames(gray=True):
        if t >= end:
            return
        if t >= start:
            yield t, frame


def recovery_after(
    recording: Recording,
    config: TouchConfig,
    light_of: Callable[[], Light | None],
    switch_at: float,
    until: float = float("inf"),
) -> float:
    """Seconds from ``switch_at`` until the known contact reads as steady light reads it, from then on to ``until``
    (inf: never): :func:`feelium.lab.touch.litroom.sensitivity_recovery` on the recording's frames, the steady light
    being the same frames from the switch on, read by a pipeline that has only known them. ``light_of()``: a new
    light feed for the recording (None without a projector stream)."""

    def reader() -> dict[str, Any]:
        light = light_of()
        pipeline = new_pipeline(recording, config, light)
        return {"pipeline": pipeline, "light": light if light is not None else _no_light, "roi": pipeline.roi}

    return litroom.sensitivity_recovery(
        _frames(recording, -np.inf, until), _frames(recording, switch_at, until), config, switch_at, reader=reader
    )


def _no_light(_t: float) -> dict[str, Any]:
    return {}


def measurable(recording: Recording) -> bool:
    """Whether recovery can be read from this recording: it must be hand-free (the spec's ``empty`` label). A hand
    near one of the five places reads as a different depth whatever the light, and a pipeline's reference after a
    hover or a hold differs from one that never saw it: the lab's twins are hand-free for that reason."""
    return recording.labels is not None and recording.labels.label == "empty"


def recoveries(
    recording: Recording, config: TouchConfig, light_of: Callable[[], Light | None]
) -> tuple[Switches, list[float]]:
    """Every labelled switch of ``recording`` and its recovery, each judged up to the next switch (none measured on
    a recording with hands: :func:`measurable`)."""
    found = switches_of(recording)
    if not measurable(recording):
        return found, []
    ends = list(found.times[1:]) + [float("inf")]
    return found, [recovery_after(recording, config, light_of, t, end) for t, end in zip(found.times, ends)]


def summarise(values: list[float], sources: list[str], unmeasurable: int) -> dict[str, Any] | None:
    """The per-condition report: recovery median and max over the measured switches, and whether every one is within
    the goal. ``never`` counts switches not recovered by the recording's end (no number: JSON has no inf);
    ``not_measurable`` the switches of recordings with hands (:func:`measurable`). None: no switch at all."""
    if not values and not unmeasurable:
        return None
    finite = [v for v in values if np.isfinite(v)]
    never = len(values) - len(finite)
    median = float(np.median(values)) if values else None
    return {
        "n": len(values),
        "recovery_s": None if not values else {
            "median": median if median is not None and np.isfinite(median) else None,
            "max": None if never or not finite else float(max(finite)),
        },
        "never": never,
        "not_measurable": unmeasurable,
        "goal_s": GOAL_S,
        "within_goal": None if not values else bool(never == 0 and max(finite) <= GOAL_S),
        "switch_times_from": {s: sources.count(s) for s in sorted(set(sources))},
    }
