"""Keeping the skin lit enough to sense touch: the projector is the touch sensor's back-light.

Two floors, both linear lifts of the canvas (``out = floor + v * (1 - floor)``,
so the face keeps its shape and only its darkest grey rises):

- ``sensing_floor``, always: no pixel is projected darker than this grey, so a
  dark eye or background still back-lights the membrane;
- ``fade_floor``, on the canvas's mean: when the whole picture goes dark (the
  wearer's video fading to black and back), the lift rises until the canvas's
  mean grey is ``fade_floor``. A press is told from a close hover by the
  *projector* light the pressed skin takes away (the frustrated reflection);
  room light is blocked alike by both. With the video black and only the
  sensing floor lit (0.28 of the flat grey's light) a tap was seen 4 times in
  12; at a floor of 0.75 grey (0.77 of the flat light) 12 in 12
  (``python -m feelium.lab.touch.dimlight``, docs/touch.md). A face at full
  brightness is above that mean and is not touched; a fade goes to a light grey
  instead of a dark one (the cost: fades are paler).

The lift is chosen from the canvas alone (no feedback from touch), so the
frame the touch service predicts is the frame shown.
"""

from __future__ import annotations

import cv2
import numpy as np

_LUMA_BGR = (0.114, 0.587, 0.299)  # cv2.COLOR_BGR2GRAY's weights: the grey the back-light prediction uses


def lift_floor(mean_grey: float, sensing_floor: float, fade_floor: float) -> float:
    """The floor that brings a canvas of mean grey ``mean_grey`` (0..1, before lifting) to a mean of at least
    ``fade_floor``, and never under ``sensing_floor``: ``f + m (1 - f) >= F`` gives ``f = (F - m) / (1 - m)``."""
    if mean_grey >= 1.0:
        return sensing_floor
    return min(1.0, max(sensing_floor, (fade_floor - mean_grey) / (1.0 - mean_grey)))


def lift_lut(floor: float) -> np.ndarray:
    """The uint8 look-up table of the lift ``floor + v (1 - floor)``."""
    return np.clip(np.round(255.0 * floor + np.arange(256) * (1.0 - floor)), 0, 255).astype(np.uint8)


class SensingLift:
    """Lifts canvases in place by the floor :func:`lift_floor` gives; tables cached per 1/255 of floor.

    The floor is measured on the picture (the face or the avatar) before the answers are drawn, and applied after:
    a whole-skin answer (``breathing``) must still brighten the skin, not be cancelled by a lift that keeps the
    mean constant.
    """

    def __init__(self, sensing_floor: float, fade_floor: float) -> None:
        self.sensing_floor = sensing_floor
        self.fade_floor = fade_floor
        self.floor = sensing_floor  # the floor measured last (and applied to the last canvas)
        self._luts: dict[int, np.ndarray | None] = {}  # per floor key: its table, or None where the scaling is exact

    def measure(self, img: np.ndarray) -> float:
        """Choose the floor for the picture ``img`` (BGR or gray uint8, not yet lifted) and return it."""
        floor = self.sensing_floor
        if self.fade_floor > self.sensing_floor:
            means = cv2.mean(img)
            grey = means[0] if img.ndim == 2 or img.shape[2] == 1 else sum(w * m for w, m in zip(_LUMA_BGR, means))
            floor = lift_floor(grey / 255.0, self.sensing_floor, self.fade_floor)
        self.floor = floor
        return floor

    def apply(self, img: np.ndarray) -> None:
        """Lift ``img`` in place by the floor last measured.

        The lift is affine, so OpenCV's saturating scale (``convertScaleAbs``: one multiply-add a byte) computes
        it about 2.5x faster than the table's look-up (0.07 against 0.17 ms a 512x384 canvas here, where the
        projector lifts ~16 canvases a second). Its float32 rounding is checked against the table once per floor
        key, on this machine, for every byte value along both of its code paths (vectorised and scalar); a key
        where any value differs keeps the table, so the lifted canvas is the table's byte for byte either way.
        """
        key = int(round(self.floor * 255.0))
        if key <= 0:
            return
        if key not in self._luts:
            lut = lift_lut(key / 255.0)
            self._luts[key] = None if _scales_exactly(key / 255.0, lut) else lut
        lut = self._luts[key]
        if lut is None:
            floor = key / 255.0
            cv2.convertScaleAbs(img, dst=img, alpha=1.0 - floor, beta=255.0 * floor)
        else:
            cv2.LUT(img, lut, dst=img)


def _scales_exactly(floor: float, lut: np.ndarray) -> bool:
    """Whether ``convertScaleAbs`` with the lift's scale and shift gives ``lut``'s value for every byte, in place,
    both in a long contiguous run (OpenCV's vector path) and one byte a row (its scalar path)."""
    run = np.tile(np.arange(256, dtype=np.uint8), 4)
    cv2.convertScaleAbs(run, dst=run, alpha=1.0 - floor, beta=255.0 * floor)
    rows = np.zeros((256, 2), np.uint8)
    rows[:, 0] = np.arange(256)
    column = rows[:, :1]  # 256 rows of one byte each: not continuous, so no row is long enough to vectorise
    cv2.convertScaleAbs(column, dst=column, alpha=1.0 - floor, beta=255.0 * floor)
    return np.array_equal(run, np.tile(lut, 4)) and np.array_equal(rows[:, 0], lut)
