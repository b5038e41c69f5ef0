"""When is the projected-light prediction good enough to raise a touch on?

At a scene cut or during a fade the whole membrane's light changes between two
camera frames. The prediction then depends most on what is least known (the
projector's latency against the camera's exposure, a blur or gamma slightly
off, a response not yet learned for the new content), and an error of a few
per cent over a face's edges looks like a shadow's sharp edge. The rule: a
camera frame whose predicted light changed, on average over the ROI, by more
than ``cut_change`` from the previous frame is *uncertain*, and the prediction
is *settled* again only ``settle_s`` of camera time after the last uncertain
frame. While unsettled the gates hold: no new touch is raised (touches already
down stay down while their shadow is seen), the reference and the photometric
response learn nothing. A talking mouth or a blink changes a small area and
keeps the frame certain; a cut or a fade does not.
"""

from __future__ import annotations

import numpy as np


class PredictionSettle:
    """Tracks whether the predicted light has been steady long enough to trust."""

    def __init__(self, *, cut_change: float, settle_s: float) -> None:
        self.cut_change = cut_change
        self.settle_s = settle_s
        self.change = 0.0  # last frame's mean absolute change of predicted light
        self.uncertain_frames = 0
        self._previous: np.ndarray | None = None
        self._last_uncertain_t: float | None = None

    def reset(self) -> None:
        self.change = 0.0
        self._previous = None
        self._last_uncertain_t = None

    def observe(self, t: float, light: np.ndarray) -> bool:
        """Feed this frame's predicted light (working resolution); True when the prediction is settled."""
        if self._previous is not None and self._previous.shape == light.shape:
            diff = np.abs(light - self._previous)
            mean = float(np.mean(diff)) if diff.size else 0.0
            self.change = mean if np.isfinite(mean) else float("inf")
        else:
            self.change = 0.0
        self._previous = light.copy()
        if self.change > self.cut_change:
            self._last_uncertain_t = t
            self.uncertain_frames += 1
        return self._last_uncertain_t is None or t - self._last_uncertain_t >= self.settle_s
