"""How each answer looks: drawing functions onto the skin canvas (BGR uint8, in place).

Every function takes the canvas, the answer and ``now``, and only touches a
crop around the answer (except the whole-skin ones), so a frame with a few
answers costs little more than the face alone. Glows are precomputed sprites
added with saturation, so overlapping answers brighten instead of hiding each
other (two palms merging turn white).
"""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np

from feelium.interactions.answers import Answer
from feelium.projector.strokes import CORE_BGR, STROKE_BGR, draw_points, polyline

RIPPLE_BGR = (255, 230, 170)
WARM_BGR = (60, 150, 255)
HEART_PARTNER_BGR = (150, 90, 255)
HEART_WEARER_BGR = (70, 40, 240)
PALM_PARTNER_BGR = (60, 140, 255)
PALM_WEARER_BGR = (255, 150, 60)
BREATH_BGR = (40, 110, 200)
SHIMMER_BGR = (255, 220, 200)
FIRE_BGR = ((0, 80, 255), (0, 180, 255), (120, 240, 255))


def fade(answer: Answer, now: float, rise_s: float = 0.15) -> float:
    """0..1 envelope: quick rise, and a fall over the last part of a timed answer (or its ``fade_from``)."""
    age = answer.age(now)
    level = min(1.0, age / rise_s) if rise_s > 0 else 1.0
    if math.isfinite(answer.until):
        start = answer.detail.get("fade_from", answer.t0 + 0.5 * (answer.until - answer.t0))
        if now > start:
            level *= max(0.0, (answer.until - now) / max(answer.until - start, 1e-6))
    return max(0.0, min(1.0, level))


@lru_cache(maxsize=32)
def _glow_sprite(radius: int) -> np.ndarray:
    """(2r+1, 2r+1) float32 Gaussian glow, 1 at the centre."""
    offs = np.arange(-radius, radius + 1, dtype=np.float32)
    g = np.exp(-0.5 * (offs / (radius / 2.5)) ** 2)
    return np.outer(g, g).astype(np.float32)


@lru_cache(maxsize=16)
def _palm_sprite(size: int) -> np.ndarray:
    """A palm-shaped glow (palm and five fingers), blurred, peak 1; ``size`` is the hand's length in px."""
    pad = size // 4
    n = size + 2 * pad
    mask = np.zeros((n, n), np.float32)
    cx, cy = n / 2, n / 2 + size * 0.12
    cv2.ellipse(mask, (int(cx), int(cy)), (int(0.26 * size), int(0.24 * size)), 0, 0, 360, 1.0, -1, cv2.LINE_AA)
    fingers = ((-0.2, -0.38, 0.2, -12), (-0.07, -0.46, 0.25, -4), (0.07, -0.46, 0.25, 4), (0.19, -0.4, 0.21, 12), (-0.33, -0.05, 0.18, -50))
    for dx, dy, length, angle in fingers:
        centre = (int(cx + dx * size), int(cy + dy * size))
        cv2.ellipse(mask, centre, (int(0.055 * size), int(length * size / 2 + 0.05 * size)), angle, 0, 360, 1.0, -1, cv2.LINE_AA)
    mask = cv2.GaussianBlur(mask, (0, 0), max(1.0, size * 0.04))
    # Centre the glow's mass on the sprite's centre: a palm contact's landing point is its centroid.
    m = cv2.moments(mask)
    shift = np.float32([[1, 0, (n - 1) / 2 - m["m10"] / m["m00"]], [0, 1, (n - 1) / 2 - m["m01"] / m["m00"]]])
    mask = cv2.warpAffine(mask, shift, (n, n), flags=cv2.INTER_LINEAR)
    return mask / max(float(mask.max()), 1e-6)


def add_sprite(canvas: np.ndarray, sprite: np.ndarray, cx: float, cy: float, color: tuple[int, int, int], gain: float) -> None:
    """canvas += gain * color * sprite, centred at (cx, cy), clipped to the canvas, saturating."""
    if gain <= 0:
        return
    h, w = canvas.shape[:2]
    sh, sw = sprite.shape
    x0, y0 = int(round(cx)) - sw // 2, int(round(cy)) - sh // 2
    ax0, ay0, ax1, ay1 = max(x0, 0), max(y0, 0), min(x0 + sw, w), min(y0 + sh, h)
    if ax0 >= ax1 or ay0 >= ay1:
        return
    part = sprite[ay0 - y0 : ay1 - y0, ax0 - x0 : ax1 - x0]
    crop = canvas[ay0:ay1, ax0:ax1]
    glow = part[:, :, None] * (np.asarray(color, np.float32) * np.float32(gain))
    np.add(crop, glow, out=glow)
    np.minimum(glow, 255.0, out=glow)
    crop[...] = glow.astype(np.uint8)


def _to_px(canvas: np.ndarray, u: float, v: float) -> tuple[float, float]:
    h, w = canvas.shape[:2]
    return u * w, v * h


def draw_ripple(canvas: np.ndarray, a: Answer, now: float) -> None:
    w = canvas.shape[1]
    cx, cy = _to_px(canvas, a.u, a.v)
    age = a.age(now)
    span = max(a.until - a.t0, 1e-6)
    for k in range(3):
        ring_age = age - 0.15 * k
        if ring_age <= 0:
            continue
        r = int(0.02 * w + 0.16 * w * ring_age / span)
        level = max(0.0, 1.0 - ring_age / span)
        color = tuple(int(c * level) for c in RIPPLE_BGR)
        cv2.circle(canvas, (int(cx), int(cy)), r, color, max(2, w // 170), cv2.LINE_AA)


def draw_warm_pulse(canvas: np.ndarray, a: Answer, now: float) -> None:
    w = canvas.shape[1]
    cx, cy = _to_px(canvas, a.u, a.v)
    span = max(a.until - a.t0, 1e-6)
    phase = min(max(a.age(now) / span, 0.0), 1.0)
    add_sprite(canvas, _glow_sprite(int(0.09 * w)), cx, cy, WARM_BGR, math.sin(math.pi * phase) * fade(a, now, 0.05))


def _heart_polygon(cx: float, cy: float, size: float) -> np.ndarray:
    ts = np.linspace(0, 2 * np.pi, 48)
    x = 16 * np.sin(ts) ** 3
    y = -(13 * np.cos(ts) - 5 * np.cos(2 * ts) - 2 * np.cos(3 * ts) - np.cos(4 * ts))
    return np.stack([cx + x * size / 32, cy + y * size / 32], axis=1).astype(np.int32)


def draw_heart(canvas: np.ndarray, a: Answer, now: float) -> None:
    w = canvas.shape[1]
    cx, cy = _to_px(canvas, a.u, a.v)
    bloom = 1.0 - math.exp(-a.age(now) / 0.15)
    wearer = a.detail.get("from") == "wearer"
    size = (0.11 if wearer else 0.08) * w * bloom
    level = fade(a, now, 0.05)
    color = HEART_WEARER_BGR if wearer else HEART_PARTNER_BGR
    add_sprite(canvas, _glow_sprite(int(0.07 * w)), cx, cy, color, 0.6 * level)
    if size >= 2:
        cv2.fillPoly(canvas, [_heart_polygon(cx, cy, size)], tuple(int(c * level) for c in color), cv2.LINE_AA)


def draw_palm_glow(canvas: np.ndarray, a: Answer, now: float) -> None:
    w = canvas.shape[1]
    u, v = a.u, a.v
    if "from_u" in a.detail:
        k = min(1.0, a.age(now) / max(a.detail.get("glide_s", 0.0), 1e-6))
        k = k * k * (3 - 2 * k)
        u = a.detail["from_u"] + (u - a.detail["from_u"]) * k
        v = a.detail["from_v"] + (v - a.detail["from_v"]) * k
    cx, cy = _to_px(canvas, u, v)
    color = PALM_WEARER_BGR if a.detail.get("side") == "wearer" else PALM_PARTNER_BGR
    pulse = 0.85 + 0.15 * math.sin(2 * math.pi * a.age(now) / 1.6)
    add_sprite(canvas, _palm_sprite(int(0.3 * w)), cx, cy, color, pulse * fade(a, now, 0.3))


def draw_breathing(canvas: np.ndarray, a: Answer, now: float) -> None:
    breath = 0.5 - 0.5 * math.cos(2 * math.pi * a.age(now) / 4.0)  # one slow breath every 4 s, starting dark
    level = (0.25 + 0.45 * breath) * fade(a, now, 1.0)
    cv2.add(canvas, tuple(int(c * level) for c in BREATH_BGR) + (0,), dst=canvas)


_SHIMMER_SCALE = 4  # the shimmer is smooth: compute it at a quarter of the canvas and upsample


@lru_cache(maxsize=4)
def _diagonal(width: int, height: int) -> np.ndarray:
    """Distance along the shimmer's travel direction of each low-resolution pixel, in canvas px."""
    s = _SHIMMER_SCALE
    xs = np.arange(0, width, s, dtype=np.float32)[None, :]
    ys = np.arange(0, height, s, dtype=np.float32)[:, None]
    return xs + 0.6 * ys


def draw_shimmer(canvas: np.ndarray, a: Answer, now: float) -> None:
    h, w = canvas.shape[:2]
    diag = _diagonal(w, h)
    travel = (a.age(now) * 0.6 * w) % (1.6 * w)
    twinkle = 0.5 + 0.5 * math.sin(2 * math.pi * a.age(now) * 2.0)
    level = (0.7 + 0.3 * twinkle) * fade(a, now, 0.3)
    band = np.exp(-0.5 * ((diag - travel + 0.3 * w) / (0.06 * w)) ** 2) * np.float32(level)
    small = (band[:, :, None] * np.asarray(SHIMMER_BGR, np.float32)).astype(np.uint8)
    cv2.add(canvas, cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR), dst=canvas)


def _polyline(canvas: np.ndarray, points: tuple[tuple[float, float], ...]) -> np.ndarray:
    h, w = canvas.shape[:2]
    return polyline(points, w, h)


def draw_stroke(canvas: np.ndarray, a: Answer, now: float) -> None:
    """The whole stroke, drawn again: the renderer keeps a round's strokes in a
    :class:`~feelium.projector.strokes.StrokeLayer` instead; this is the picture that layer must match."""
    draw_points(canvas, a.detail.get("points", ()), STROKE_BGR, CORE_BGR)


def draw_ignite(canvas: np.ndarray, a: Answer, now: float) -> None:
    w = canvas.shape[1]
    level = fade(a, now, 0.1)
    age = a.age(now)
    flicker = 0.5 + 0.5 * math.sin(2 * math.pi * 7.0 * age)
    for points in a.detail.get("strokes", ()):
        if len(points) < 2:
            continue
        line = _polyline(canvas, points)
        for color, thickness in zip(FIRE_BGR, (0.05, 0.03, 0.012)):
            t = max(2, int(w * thickness * (0.8 + 0.4 * flicker)))
            cv2.polylines(canvas, [line], False, tuple(int(c * level) for c in color), t, cv2.LINE_AA)
    cx, cy = _to_px(canvas, a.u, a.v)
    r = int(0.05 * w + 0.4 * w * min(age, 1.0))
    cv2.circle(canvas, (int(cx), int(cy)), r, tuple(int(c * level * max(0.0, 1.0 - age)) for c in FIRE_BGR[1]), max(2, w // 120), cv2.LINE_AA)


def draw_prompt(canvas: np.ndarray, a: Answer, now: float) -> None:
    w = canvas.shape[1]
    text = str(a.detail.get("text", ""))
    scale = w / 700
    thickness = max(1, w // 300)
    (tw, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)
    cx, cy = _to_px(canvas, a.u, a.v)
    level = fade(a, now, 0.2)
    cv2.putText(canvas, text, (int(cx - tw / 2), int(cy + th / 2)), cv2.FONT_HERSHEY_SIMPLEX, scale,
                tuple(int(255 * level) for _ in range(3)), thickness, cv2.LINE_AA)


DRAWERS = {
    "ripple": draw_ripple,
    "warm_pulse": draw_warm_pulse,
    "heart": draw_heart,
    "palm_glow": draw_palm_glow,
    "breathing": draw_breathing,
    "shimmer": draw_shimmer,
    "stroke": draw_stroke,
    "ignite": draw_ignite,
    "prompt": draw_prompt,
}
