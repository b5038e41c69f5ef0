"""A synthetic face on the skin for the touch tests: projected light that changes, room light that does not.

The camera sees ``backlight * (share * light + (1 - share) * room_open) * (1 - contact)``: a hover only
takes away room light (``room_open``), a pressed patch takes away light of both kinds. ``light`` is the
projector's light relative to flat grey: an oval face with eyes and a mouth that open and close, a head
that sways, a cut to another framing every ``cut_every_s`` and a fade to black and back.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from tests.touch.synth import H, W, backlight

SHARE = 0.45  # projector's share of the membrane's light under flat grey (the rest is room light)
BLACK = 0.04  # a black projector pixel's light relative to flat


def face_light(t: float, *, cut_every_s: float = 2.0, fade_at_s: float = 3.0) -> np.ndarray:
    """(H, W) float32 projected light relative to flat grey at time ``t``."""
    scene = int(t // cut_every_s) % 2
    cx = W / 2 + 10 * math.sin(2 * math.pi * 0.4 * t) + (0, 25)[scene]
    cy = H / 2 + 5 * math.sin(2 * math.pi * 0.3 * t)
    scale = (1.0, 0.7)[scene]
    img = np.full((H, W), 0.3, np.float32)
    cv2.ellipse(img, (int(cx), int(cy)), (int(40 * scale), int(50 * scale)), 0, 0, 360, 1.3, -1)
    blink = 1 if (t % 1.7) < 0.15 else 4
    for ex in (-14, 14):
        cv2.ellipse(img, (int(cx + ex * scale), int(cy - 12 * scale)), (int(6 * scale), blink), 0, 0, 360, BLACK, -1)
    mouth = int(2 + 6 * abs(math.sin(2 * math.pi * 2.0 * t)))
    cv2.ellipse(img, (int(cx), int(cy + 22 * scale)), (int(12 * scale), mouth), 0, 0, 360, BLACK, -1)
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    p = t - fade_at_s
    fade = 1.0 if p < 0 or p > 1.0 else (max(0.0, 1 - p / 0.35) if p < 0.5 else min(1.0, (p - 0.65) / 0.35))
    return np.maximum(img * np.float32(fade), np.float32(BLACK))


def frame(
    t: float,
    light: np.ndarray,
    *,
    hover: tuple[float, float, float] | None = None,
    press: tuple[float, float] | None = None,
    rng: np.random.Generator,
) -> np.ndarray:
    """One uint8 frame; ``hover`` = (x, y, occlusion) of a blurred hand shadow, ``press`` = (x, y) of a fingertip."""
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float32)
    room = np.ones((H, W), np.float32)
    if hover is not None:
        hx, hy, occ = hover
        room = room - occ * np.exp(-((xs - hx) ** 2 + (ys - hy) ** 2) / (2 * 7.0**2))
    img = backlight() * (SHARE * light + (1 - SHARE) * room)
    if press is not None:
        px, py = press
        disc = (((xs - px) ** 2 + (ys - py) ** 2) <= 6.0**2).astype(np.float32)
        img = img * (1.0 - 0.7 * cv2.GaussianBlur(disc, (0, 0), 1.0))
    img = img + rng.normal(0.0, 1.5, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
