"""A thermal frame as a coloured terminal picture, so a person can check the wiring in seconds.

Each text line shows two sensor rows with the upper half block: the upper
row as the foreground colour and the lower as the background, so 32 x 24
pixels fit 32 x 12 characters. Truecolor where the terminal says so
(``COLORTERM``), the 256-colour palette elsewhere.
"""

from __future__ import annotations

import os

import numpy as np

# dark blue -> purple -> red -> orange -> pale yellow (an "iron" palette)
_STOPS = np.array([[0, 0, 40], [90, 0, 140], [200, 30, 60], [250, 140, 0], [255, 250, 190]], dtype=np.float64)


def colours(frame: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """(rows, cols, 3) uint8 RGB; NaN pixels grey."""
    span = max(hi - lo, 1e-6)
    x = np.clip((np.nan_to_num(frame, nan=lo) - lo) / span, 0.0, 1.0) * (len(_STOPS) - 1)
    i = np.minimum(x.astype(int), len(_STOPS) - 2)
    f = (x - i)[..., None]
    rgb = _STOPS[i] * (1 - f) + _STOPS[i + 1] * f
    rgb[~np.isfinite(frame)] = (128, 128, 128)
    return rgb.astype(np.uint8)


def _ansi256(rgb: np.ndarray) -> int:
    r, g, b = (int(round(int(c) / 255 * 5)) for c in rgb)
    return 16 + 36 * r + 6 * g + b


def _code(rgb: np.ndarray, background: bool, truecolor: bool) -> str:
    if truecolor:
        return f"\x1b[{48 if background else 38};2;{rgb[0]};{rgb[1]};{rgb[2]}m"
    return f"\x1b[{48 if background else 38};5;{_ansi256(rgb)}m"


def supports_truecolor() -> bool:
    return os.environ.get("COLORTERM", "").lower() in ("truecolor", "24bit")


def render(frame: np.ndarray, *, truecolor: bool | None = None) -> str:
    """The frame as lines of half-block characters (no trailing newline), scaled to its own min..max."""
    truecolor = supports_truecolor() if truecolor is None else truecolor
    finite = frame[np.isfinite(frame)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    rgb = colours(frame, lo, hi)
    rows = rgb.shape[0]
    lines = []
    for r in range(0, rows, 2):
        cells = []
        for c in range(rgb.shape[1]):
            top = rgb[r, c]
            bottom = rgb[r + 1, c] if r + 1 < rows else np.zeros(3, dtype=np.uint8)
            cells.append(_code(top, False, truecolor) + _code(bottom, True, truecolor) + "\u2580")
        lines.append("".join(cells) + "\x1b[0m")
    return "\n".join(lines)


__all__ = ["colours", "render", "supports_truecolor"]
