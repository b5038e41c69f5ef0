"""The default avatar: a friendly face on the skin when the headset sends none.

Drawn procedurally (no asset files) on the skin canvas, laid out to match the
default envelope regions (forehead = head, blush = cheeks, chin = palm zone).
It blinks and breathes a little so the blimp looks alive; the face-video
robustness test uses the same animation (`talking=True` moves the mouth) as a
moving face that changes the back-light.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

SKIN_BGR = (120, 170, 215)
FEATURE_BGR = (50, 45, 60)
BACKGROUND_BGR = (70, 50, 40)


class Avatar:
    """Renders the animated default face at a canvas size."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        base = np.full((height, width, 3), BACKGROUND_BGR, np.uint8)
        c = (width // 2, height // 2)
        cv2.ellipse(base, c, (int(0.44 * width), int(0.48 * height)), 0, 0, 360, SKIN_BGR, -1, cv2.LINE_AA)
        for cu in (0.27, 0.73):
            blush = np.zeros_like(base)
            cv2.ellipse(blush, (int(cu * width), int(0.6 * height)), (int(0.07 * width), int(0.05 * height)), 0, 0, 360, (40, 30, 70), -1, cv2.LINE_AA)
            base = cv2.add(base, cv2.GaussianBlur(blush, (0, 0), 0.02 * width))
        self._base = base

    def pose(self, t: float, talking: bool = False) -> tuple[int, ...]:
        """What the face at time ``t`` looks like, in the integer pixel positions it is drawn with: two times
        with the same pose draw the same image (the avatar moves a pixel only a few times a second, so the
        projector can skip most of its frames)."""
        w, h = self.width, self.height
        sway = 0.012 * w * math.sin(2 * math.pi * t / 5.0)
        blink = (t % 4.3) < 0.15
        eye_h = max(1, int(0.008 * h)) if blink else int(0.045 * h)
        eyes = tuple(int(cu * w + sway) for cu in (0.36, 0.64))
        mouth_x = int(0.5 * w + sway)
        if talking:
            open_ = 0.5 + 0.5 * math.sin(2 * math.pi * 3.1 * t) * math.sin(2 * math.pi * 0.7 * t)
            return (*eyes, eye_h, mouth_x, int((0.01 + 0.06 * max(open_, 0.0)) * h))
        return (*eyes, eye_h, mouth_x, -1)

    def render(self, t: float, talking: bool = False, out: np.ndarray | None = None) -> np.ndarray:
        """The face at time ``t`` (seconds): blinking every few seconds, mouth moving when ``talking``; drawn
        into ``out`` (same size, BGR uint8) when given."""
        return self.draw(self.pose(t, talking), out)

    def draw(self, pose: tuple[int, ...], out: np.ndarray | None = None) -> np.ndarray:
        """The face in ``pose`` (:meth:`pose`), into ``out`` when given."""
        w, h = self.width, self.height
        if out is None:
            img = self._base.copy()
        else:
            img = out
            np.copyto(img, self._base)
        left_x, right_x, eye_h, mouth_x, mouth_h = pose
        for x in (left_x, right_x):
            cv2.ellipse(img, (x, int(0.42 * h)), (int(0.035 * w), eye_h), 0, 0, 360, FEATURE_BGR, -1, cv2.LINE_AA)
        if mouth_h >= 0:
            cv2.ellipse(img, (mouth_x, int(0.72 * h)), (int(0.09 * w), mouth_h), 0, 0, 360, FEATURE_BGR, -1, cv2.LINE_AA)
        else:
            cv2.ellipse(img, (mouth_x, int(0.7 * h)), (int(0.1 * w), int(0.05 * h)), 0, 10, 170, FEATURE_BGR, max(2, w // 120), cv2.LINE_AA)
        return img
