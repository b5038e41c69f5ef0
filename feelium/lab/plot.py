"""Small line plots as PNG, drawn with OpenCV.

Figures (the paper's anchoring plot, flight step responses) must be producible
on the blimp and in CI without pulling matplotlib onto a 512 MB board, and a
time series with axes, a legend and threshold lines is all they need.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

PALETTE: tuple[tuple[int, int, int], ...] = (
    (180, 119, 31),  # blue (BGR)
    (14, 127, 255),  # orange
    (44, 160, 44),  # green
    (40, 39, 214),  # red
    (189, 103, 148),  # purple
    (75, 86, 140),  # brown
)
_FONT = cv2.FONT_HERSHEY_SIMPLEX


@dataclass(frozen=True)
class Series:
    """One line: ``x`` and ``y`` of equal length; non-finite points break the line."""

    x: np.ndarray
    y: np.ndarray
    label: str
    color: tuple[int, int, int] | None = None


def nice_ticks(lo: float, hi: float, count: int = 6) -> list[float]:
    """Round tick values covering [lo, hi] (1, 2, 5 times a power of ten)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo]
    raw = (hi - lo) / max(count - 1, 1)
    magnitude = 10 ** math.floor(math.log10(raw))
    step = next(m * magnitude for m in (1, 2, 5, 10) if m * magnitude >= raw)
    first = math.ceil(lo / step) * step
    ticks = []
    value = first
    while value <= hi + step * 1e-9:
        ticks.append(round(value, 12))
        value += step
    return ticks


def _limits(values: list[np.ndarray], extra: Sequence[float] = ()) -> tuple[float, float]:
    finite = [v[np.isfinite(v)] for v in values]
    parts = [f for f in finite if f.size] + ([np.asarray(extra, dtype=float)] if extra else [])
    if not parts:
        return 0.0, 1.0
    allv = np.concatenate(parts)
    lo, hi = float(allv.min()), float(allv.max())
    if hi - lo < 1e-12:
        lo, hi = lo - 0.5, hi + 0.5
    pad = 0.05 * (hi - lo)
    return lo - pad, hi + pad


def _fmt(value: float) -> str:
    return f"{value:g}"


def line_plot(
    path: str | Path,
    series: Sequence[Series],
    *,
    title: str,
    xlabel: str,
    ylabel: str,
    hlines: Sequence[tuple[float, str]] = (),
    size: tuple[int, int] = (960, 540),
) -> Path:
    """Draw ``series`` (and labelled horizontal lines) into a PNG at ``path``; returns the path."""
    width, height = size
    left, right, top, bottom = 80, 20, 50, 60
    img = np.full((height, width, 3), 255, np.uint8)
    xlo, xhi = _limits([np.asarray(s.x, float) for s in series])
    ylo, yhi = _limits([np.asarray(s.y, float) for s in series], [v for v, _ in hlines])
    pw, ph = width - left - right, height - top - bottom

    def to_px(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        px = left + (x - xlo) / (xhi - xlo) * pw
        py = top + (1.0 - (y - ylo) / (yhi - ylo)) * ph
        return px, py

    for tick in nice_ticks(xlo, xhi):
        px, _ = to_px(np.array([tick]), np.array([ylo]))
        x = int(round(px[0]))
        cv2.line(img, (x, top), (x, top + ph), (235, 235, 235), 1)
        cv2.putText(img, _fmt(tick), (x - 12, top + ph + 20), _FONT, 0.45, (60, 60, 60), 1, cv2.LINE_AA)
    for tick in nice_ticks(ylo, yhi):
        _, py = to_px(np.array([xlo]), np.array([tick]))
        y = int(round(py[0]))
        cv2.line(img, (left, y), (left + pw, y), (235, 235, 235), 1)
        cv2.putText(img, _fmt(tick), (8, y + 5), _FONT, 0.45, (60, 60, 60), 1, cv2.LINE_AA)
    cv2.rectangle(img, (left, top), (left + pw, top + ph), (0, 0, 0), 1)

    for value, label in hlines:
        _, py = to_px(np.array([xlo]), np.array([value]))
        y = int(round(py[0]))
        for x0 in range(left, left + pw, 14):
            cv2.line(img, (x0, y), (min(x0 + 7, left + pw), y), (80, 80, 80), 1, cv2.LINE_AA)
        cv2.putText(img, label, (left + pw - 8 * len(label) - 10, y - 6), _FONT, 0.45, (80, 80, 80), 1, cv2.LINE_AA)

    legend_entries = 0
    for index, s in enumerate(series):
        color = s.color or PALETTE[index % len(PALETTE)]
        x, y = np.asarray(s.x, float), np.asarray(s.y, float)
        px, py = to_px(x, y)
        ok = np.isfinite(px) & np.isfinite(py)
        # Split at non-finite points so gaps stay gaps.
        breaks = np.flatnonzero(~ok)
        start = 0
        for stop in [*breaks.tolist(), len(px)]:
            run = np.stack([px[start:stop], py[start:stop]], axis=1)
            if len(run) >= 2:
                cv2.polylines(img, [np.round(run * 16).astype(np.int32)], False, color, 2, cv2.LINE_AA, shift=4)
            start = stop + 1
        if s.label:  # an unlabelled series (one of many of a kind) draws no legend entry
            ly = top + 18 + 20 * legend_entries
            cv2.line(img, (left + 12, ly - 4), (left + 36, ly - 4), color, 3)
            cv2.putText(img, s.label, (left + 42, ly), _FONT, 0.5, (30, 30, 30), 1, cv2.LINE_AA)
            legend_entries += 1

    cv2.putText(img, title, (left, 30), _FONT, 0.65, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, xlabel, (left + pw // 2 - 4 * len(xlabel), height - 15), _FONT, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    ylab = np.full((24, max(8 * len(ylabel) + 10, 10), 3), 255, np.uint8)
    cv2.putText(ylab, ylabel, (4, 17), _FONT, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    ylab = cv2.rotate(ylab, cv2.ROTATE_90_COUNTERCLOCKWISE)
    h = min(ylab.shape[0], ph)
    y0 = top + (ph - h) // 2
    img[y0 : y0 + h, 48 : 48 + ylab.shape[1]] = np.minimum(img[y0 : y0 + h, 48 : 48 + ylab.shape[1]], ylab[:h])

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), img):
        raise OSError(f"{path}: cannot write PNG")
    return path
