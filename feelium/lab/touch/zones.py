"""`feelium eval`'s breakdown by zone of the front face (issue 17, point 3; added key ``zones``).

The front face is not one rectangle: at its rim the back-light is dimmest and
the fisheye compresses the membrane most (fewer pixels per mm), so a pipeline
that is right at the centre may be wrong there, and the overall figures hide
it. Each labelled trial is put in the zone of its *labelled* contact's skin
point (the first contact's position at its onset, else the trial's target),
mapped to skin ``u, v`` through the recording's face model
(:class:`feelium.skin.face.FaceModel`, ``meta.face``); the zone is
``max(|u - 0.5|, |v - 0.5|) / 0.5``, cut in thirds as the face bench's
(:mod:`feelium.lab.touch.face_zones`), the edge running up to the rim.
Each zone's trials are then scored exactly as the whole dataset
(:func:`feelium.lab.touch.evaluate.score_trials`), so recall and
localisation error mean the same per zone as overall. A recording without a
face model has no skin ``u, v`` (its ``u, v`` span the paper's rectangle, not
the face), so it has no zone; with none, the key is null.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from feelium.skin.face import FaceModel

ZONES = ("centre", "mid", "edge")
ZONE_CUTS = (1.0 / 3.0, 2.0 / 3.0)  # of the face's half-extent from its centre


def face_zone(u: float, v: float) -> str | None:
    """The zone of skin point ``(u, v)``; None off the face (outside ``[0, 1]``, or NaN)."""
    if not (0.0 <= u <= 1.0 and 0.0 <= v <= 1.0):  # NaN fails both
        return None
    rho = max(abs(u - 0.5), abs(v - 0.5)) / 0.5
    if rho < ZONE_CUTS[0]:
        return "centre"
    return "mid" if rho < ZONE_CUTS[1] else "edge"


def trial_point(trial: Any) -> tuple[float, float] | None:
    """Camera pixel of a trial's labelled place: its first contact at onset, else its target (None without)."""
    contacts = trial.labels.contacts
    if contacts:
        first = min(contacts, key=lambda c: c.t_on)
        at = first.position_at(first.t_on)
        if at is not None:
            return at
    return trial.labels.target


def trial_zone(trial: Any, face: FaceModel | None) -> str | None:
    """The zone of a trial on ``face`` (None without a face model or a labelled place)."""
    point = trial_point(trial)
    if face is None or point is None:
        return None
    u, v = face.to_uv(point[0], point[1])
    return face_zone(float(np.asarray(u)), float(np.asarray(v)))


def score_zones(trials: list[Any], score: Callable[[list[Any]], dict[str, Any]]) -> dict[str, Any] | None:
    """Per zone: trials, recall, negatives fired and localisation error, by ``score`` on the zone's trials.

    ``score`` is :func:`feelium.lab.touch.evaluate.score_trials` (passed in, so the
    scoring stays in one place). Null when no trial has a zone; a zone without
    trials is null.
    """
    by_zone: dict[str, list[Any]] = {zone: [] for zone in ZONES}
    placed = 0
    for trial in trials:
        zone = trial_zone(trial, trial.face)
        if zone is not None:
            by_zone[zone].append(trial)
            placed += 1
    if not placed:
        return None
    out: dict[str, Any] = {}
    for zone in ZONES:
        if not by_zone[zone]:
            out[zone] = None
            continue
        scored = score(by_zone[zone])
        t = scored["trials"]
        out[zone] = {
            "n": t["n"],
            "tp": t["tp"],
            "fn": t["fn"],
            "fp": t["fp"],
            "tn": t["tn"],
            "recall": t["recall"],
            "localisation": {"n": scored["localisation"]["n"], "error_px": scored["localisation"]["error_px"]},
        }
    out["unplaced"] = len(trials) - placed
    return out
