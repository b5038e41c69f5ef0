"""Fitting the gates' thresholds on labelled continuous clips, as the paper fits its threshold.

The paper fits its anchoring threshold on the first 60 % of each clip. Here,
from the contact clip's contact frames (positives) and the hover clip's frames
(negatives), both restricted to their first 60 %:

- ``contact_edge``: the edge sharpness (steepest depth gradient at the
  fingertip) that best tells contact frames from hover frames, taken in the
  middle of the range of equally good thresholds, so the margin to both sides
  is the same; the clips are then replayed with it, because the anchoring
  score counts from each landing on a contact edge;
- ``anchor_threshold``: the sustained-anchoring score threshold with the best
  balanced accuracy;
- ``instant_depth``: just above the deepest core any hover frame showed (plus
  a small margin), so the instant gate never fires on that hover; it is kept
  at least as high as the fitted anchor threshold.

The remaining 40 % is left for `feelium eval` to judge the fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feelium.lab.touch.evaluate import balanced_accuracy_curve, fit_threshold, split_clip

INSTANT_MARGIN = 0.04


@dataclass(frozen=True)
class ClipSeries:
    """Per-frame series of one clip, as replay produced them."""

    label: str
    t: np.ndarray
    anchor: np.ndarray
    core_depth: np.ndarray
    edge: np.ndarray
    contact: np.ndarray  # bool: labelled contact at this frame


@dataclass(frozen=True)
class Fit:
    contact_edge: float
    anchor_threshold: float
    instant_depth: float
    positives: int
    negatives: int

    def values(self) -> dict[str, float]:
        return {
            "contact_edge": round(self.contact_edge, 4),
            "anchor_threshold": round(self.anchor_threshold, 4),
            "instant_depth": round(self.instant_depth, 4),
        }

    def to_toml(self) -> str:
        lines = [
            "# Fitted by `feelium calibrate touch` on the first 60 % of the contact and hover clips",
            f"# ({self.positives} contact frames, {self.negatives} hover frames).",
            "[touch]",
        ]
        lines += [f"{key} = {value!r}" for key, value in self.values().items()]
        return "\n".join(lines) + "\n"


def _fit_samples(clips: list[ClipSeries], series: str) -> tuple[np.ndarray, np.ndarray]:
    """(contact-frame values, hover-frame values) of one series over the first 60 % of each clip."""
    pos, neg = [], []
    for clip in clips:
        fit = split_clip(clip.t)
        values = getattr(clip, series)
        if clip.label == "contact":
            pos.append(values[fit & clip.contact])
        elif clip.label == "hover":
            neg.append(values[fit])
    if not pos or not neg:
        raise ValueError("calibration needs a labelled continuous 'contact' clip and a 'hover' clip")
    positives, negatives = np.concatenate(pos), np.concatenate(neg)
    if positives.size == 0 or negatives.size == 0:
        raise ValueError("the clips hold no contact frames or no hover frames in their first 60 %")
    return positives, negatives


def fit_centred_threshold(positives: np.ndarray, negatives: np.ndarray) -> float:
    """The middle of the widest interval of thresholds with the best balanced accuracy (equal margin both sides).

    A threshold ``th`` counts values >= th as contact. Between neighbouring
    sorted values the balanced accuracy is constant, so every threshold in
    ``(values[i - 1], values[i]]`` scores like ``values[i]``; consecutive best
    values join into one interval.
    """
    values = np.unique(np.concatenate([positives, negatives]))
    candidates = np.append(values, values[-1] + 1e-6)  # the last: above everything
    ba = balanced_accuracy_curve(positives, negatives, candidates)
    best = ba >= ba.max() - 1e-12
    widest, centre = -1.0, float(candidates[int(np.argmax(best))])
    k = 0
    while k < candidates.size:
        if not best[k]:
            k += 1
            continue
        start = k
        while k + 1 < candidates.size and best[k + 1]:
            k += 1
        low = candidates[start - 1] if start > 0 else candidates[start]
        width = candidates[k] - low
        if width > widest:
            widest, centre = width, float(0.5 * (low + candidates[k]))
        k += 1
    return centre


def fit_edge(clips: list[ClipSeries]) -> float:
    """The contact-edge threshold from the clips' per-frame edge sharpness."""
    return fit_centred_threshold(*_fit_samples(clips, "edge"))


def fit_gates(clips: list[ClipSeries], contact_edge: float) -> Fit:
    """Fit the depth thresholds on clips replayed with ``contact_edge``; ValueError naming what is missing."""
    pos, neg = _fit_samples(clips, "anchor")
    threshold = fit_threshold(pos, neg)
    assert threshold is not None
    _, hover_core = _fit_samples(clips, "core_depth")
    instant = float(min(max(float(hover_core.max()) + INSTANT_MARGIN, threshold), 0.99))
    return Fit(
        contact_edge=contact_edge,
        anchor_threshold=float(threshold),
        instant_depth=instant,
        positives=int(pos.size),
        negatives=int(neg.size),
    )
