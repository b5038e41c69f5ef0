"""How far the hardest cases sit from each gate's threshold (issue 17, point 5: margins, not luck).

A recall of 1 and no false positive say nothing about the next hover that
comes a little closer: the margins do. For each gate, each trial gets the
score that decides it:

- a negative trial its *largest* score anywhere (what would fire it);
- a touch trial its largest score inside its labelled contacts, widened as the
  trial scoring widens them (what detects it).

The hardest negative is the largest negative score, the hardest positive the
smallest positive one; the margins are ``threshold - hardest negative`` and
``hardest positive - threshold``, both positive when the gate separates the
trials, and their size is how much closer a hover may come (or how much
shallower a press may get) before the gate's decision flips.

The gates' per-frame scores, as the pipeline sees them (``feelium.touch.gates``):

- *edge*: the deepest candidate's contact edge (landing needs it at least
  ``contact_edge``);
- *instant*: the deepest candidate's core depth, with or without an edge: the
  instant gate fires on a core past both thresholds, so its two margins are
  read together (a hover deep enough for the depth threshold is held off by
  the edge margin alone);
- *sustained*: the anchoring score (the rolling minimum since landing, 0
  without an edge). A contact shorter than ``anchor_min_age_s`` can never pass
  it by design (taps are the instant gate's), so only touch trials whose
  longest contact lasts that long count as its positives;
- *projected*: the largest projected depth of a candidate, the share of the
  projector's own light its shadow took (``feelium.touch.roomshare``: a hand
  above the membrane takes none, so under ``contact_projected_depth`` a shadow
  cannot land). Only where the share was known (NaN frames do not count) and
  only when that gate is on; a recording whose share was never known gives
  this gate no score.

Pure: arrays, timestamps and labels in, numbers out.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from feelium.recording import Contact


@dataclass(frozen=True)
class GateThresholds:
    """What the margins are measured against: the gates' thresholds in use."""

    contact_edge: float
    instant_depth: float
    anchor_threshold: float
    anchor_min_age_s: float
    contact_projected_depth: float = 0.0  # the projector-light gate (0: off, no margin reported for it)


@dataclass(frozen=True)
class GateSeries:
    """One recording's per-frame series the gates decide on, and its labelled contacts."""

    t: np.ndarray
    anchor: np.ndarray  # the sustained gate's score
    core_depth: np.ndarray  # the deepest candidate's core ...
    edge: np.ndarray  # ... and its contact edge
    contacts: tuple[Contact, ...]
    negative: bool  # a negative trial (hover, disturbance, empty) or a hover clip
    projected: np.ndarray | None = None  # the projector-light gate's score (NaN where the share was unknown)


def gate_margin(negatives: Iterable[float], positives: Iterable[float], threshold: float) -> dict[str, Any]:
    """Hardest negative and positive scores and their signed distances to ``threshold`` (None when absent)."""
    neg, pos = list(negatives), list(positives)
    hardest_neg = max(neg) if neg else None
    hardest_pos = min(pos) if pos else None
    return {
        "threshold": float(threshold),
        "hardest_negative": hardest_neg,
        "hardest_positive": hardest_pos,
        "negative_margin": None if hardest_neg is None else float(threshold - hardest_neg),
        "positive_margin": None if hardest_pos is None else float(hardest_pos - threshold),
        "negatives": len(neg),
        "positives": len(pos),
    }


def _max_within(t: np.ndarray, scores: np.ndarray, windows: list[tuple[float, float]]) -> float | None:
    """The largest finite score inside ``windows`` (None when there is none)."""
    inside = np.zeros(t.size, bool)
    for w0, w1 in windows:
        inside |= (t >= w0) & (t <= w1)
    values = scores[inside & np.isfinite(scores)]
    return float(values.max()) if values.size else None


def margins(
    recordings: list[GateSeries],
    gates: GateThresholds,
    *,
    widen: tuple[float, float] = (0.0, 0.0),
    per_contact: bool = False,
) -> dict[str, dict[str, Any]]:
    """Per gate (``edge``, ``instant``, ``sustained``, and ``projected`` when that gate is on),
    :func:`gate_margin` over ``recordings``.

    ``widen`` = (before, after): how far each labelled contact is widened when
    looking for its positive score (the trial scoring's window; clips use none).
    A trial is one positive (detected when any of its contacts is);
    ``per_contact`` makes every contact its own positive, as a clip's presses are.
    """
    thresholds = {"edge": gates.contact_edge, "instant": gates.instant_depth, "sustained": gates.anchor_threshold}
    if gates.contact_projected_depth > 0.0:
        thresholds["projected"] = gates.contact_projected_depth
    neg: dict[str, list[float]] = {gate: [] for gate in thresholds}
    pos: dict[str, list[float]] = {gate: [] for gate in thresholds}
    for rec in recordings:
        if rec.t.size == 0:
            continue
        series = {"edge": rec.edge, "instant": rec.core_depth, "sustained": rec.anchor}
        if "projected" in thresholds and rec.projected is not None:
            series["projected"] = rec.projected
        if rec.negative:
            for gate, scores in series.items():
                best = _max_within(rec.t, scores, [(-np.inf, np.inf)])
                if best is not None:
                    neg[gate].append(best)
            continue
        if not rec.contacts:
            continue
        units = [(c,) for c in rec.contacts] if per_contact else [rec.contacts]
        for unit in units:
            windows = [(c.t_on - widen[0], c.t_off + widen[1]) for c in unit]
            for gate, scores in series.items():
                if gate == "sustained" and max(c.t_off - c.t_on for c in unit) < gates.anchor_min_age_s:
                    continue
                best = _max_within(rec.t, scores, windows)
                if best is not None:
                    pos[gate].append(best)
    return {gate: gate_margin(neg[gate], pos[gate], threshold) for gate, threshold in thresholds.items()}
