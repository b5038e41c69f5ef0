"""Fitting the gates' thresholds on labelled continuous clips, as the paper fits its threshold.

The paper fits its anchoring threshold on the first 60 % of each clip. Here,
from the contact clip's contact frames (positives) and the hover clip's frames
(negatives), both restricted to their first 60 %:

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

from feelium.touch.evaluate import fit_threshold, split_clip

INSTANT_MARGIN = 0.04


@dataclass(frozen=True)
class ClipSeries:
    """Per-frame series of one clip, as replay produced them."""

    label: str
    t: np.ndarray
    anchor: np.ndarray
    core_depth: np.ndarray
    contact: np.ndarray  # bool: labelled contact at this frame


@dataclass(frozen=True)
class Fit:
    anchor_threshold: float
    instant_depth: float
    positives: int
    negatives: int

    def values(self) -> dict[str, float]:
        return {"anchor_threshold": round(self.anchor_threshold, 4), "instant_depth": round(self.instant_depth, 4)}

    def to_toml(self) -> str:
        lines = [
            "# Fitted by `feelium calibrate touch` on the first 60 % of the contact and hover clips",
            f"# ({self.positives} contact frames, {self.negatives} hover frames).",
            "[touch]",
        ]
        lines += [f"{key} = {value!r}" for key, value in self.values().items()]
        return "\n".join(lines) + "\n"


def fit_gates(clips: list[ClipSeries]) -> Fit:
    """Fit the thresholds; ValueError naming what is missing when the clips cannot support a fit."""
    pos_anchor, neg_anchor, neg_core = [], [], []
    for clip in clips:
        fit = split_clip(clip.t)
        if clip.label == "contact":
            pos_anchor.append(clip.anchor[fit & clip.contact])
        elif clip.label == "hover":
            neg_anchor.append(clip.anchor[fit])
            neg_core.append(clip.core_depth[fit])
    if not pos_anchor or not neg_anchor:
        raise ValueError("calibration needs a labelled continuous 'contact' clip and a 'hover' clip")
    pos = np.concatenate(pos_anchor)
    neg = np.concatenate(neg_anchor)
    if pos.size == 0 or neg.size == 0:
        raise ValueError("the clips hold no contact frames or no hover frames in their first 60 %")
    threshold = fit_threshold(pos, neg)
    assert threshold is not None
    hover_core = float(np.concatenate(neg_core).max())
    instant = float(min(max(hover_core + INSTANT_MARGIN, threshold), 0.99))
    return Fit(anchor_threshold=float(threshold), instant_depth=instant, positives=int(pos.size), negatives=int(neg.size))
