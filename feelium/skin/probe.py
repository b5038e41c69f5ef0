"""The probe: a faint, slow pattern the projector lays over a static skin so touch can tell room light from its own.

On a skin that shows nothing changing (no one inside, a still avatar) the
camera cannot tell the projector's light from the room's, and in a lit room
that is what separates a contact from a hover (:mod:`feelium.touch.roomshare`).
The probe modulates the projected light by ``1 + level(t) * s(x, y)``, ``level(t) = amplitude * sin(2 pi t / period)``,
with ``s`` a checkerboard of +-1 cells in *camera* pixels: half the skin brightens
while the other half dims, so the skin's mean (what the room returns, what an
auto-exposure meters) does not move, and every cell's own light varies by a
known amount. The projector lays it through its calibration map
(:mod:`feelium.projector.probe`), the touch side is told the level of every
frame shown and mixes them over each camera exposure (:class:`ProbeLevels`);
both sides meet here, the layer they share.

Stated parameters (not fitted to detector scores): a 0.5 s period, cells of
64 px of a 640-wide camera (32 mm on the paper's camera scale; scaled with the
camera's width: a few coarse tiles of the touch pipeline each, so most tiles
lie inside one cell). The period is short against a hand's approach (a shadow
growing under a tile over a second, while a slow probe happened to rise, read
as light following the projector: with a 2 s period the share came out 0.1
low under one tap and it was lost) and long against the camera's frame and the
projector's latency (7.5 camera frames per period at 15 fps). The amplitude,
3 %, is 1.5-3 times the threshold contrast of a counterphase pattern at 2 Hz of
these sizes in a dim room (the room's light dilutes it where the probe is
needed); 1 % would be at threshold but made the share's fit too noisy and lost
taps (docs/projector.md, *The probe*). The learning's variance threshold
(:data:`feelium.touch.roomshare.MIN_LIGHT_VAR`) follows :data:`AMPLITUDE`.
"""

from __future__ import annotations

import math
from collections import deque

import cv2
import numpy as np

AMPLITUDE = 0.03
PERIOD_S = 0.5
CELL_PX = 64  # at REFERENCE_WIDTH: a cell is the same part of the skin whatever the camera's resolution
REFERENCE_WIDTH = 640


def cell_for(width: int) -> int:
    """The probe's cell size in pixels of a camera ``width`` pixels wide."""
    return max(1, round(CELL_PX * width / REFERENCE_WIDTH))


def probe_pattern(width: int, height: int, cell_px: int | None = None) -> np.ndarray:
    """The checkerboard ``s`` (H, W) float32 of +-1 cells (``cell_px``: default :func:`cell_for` the width)."""
    cell = cell_for(width) if cell_px is None else cell_px
    yy, xx = np.mgrid[0:height, 0:width]
    return np.where(((xx // cell) + (yy // cell)) % 2 == 0, 1.0, -1.0).astype(np.float32)


def pattern_on_grid(pattern: np.ndarray, frame_size: tuple[int, int], box: tuple[int, int, int, int]) -> np.ndarray:
    """The camera-size ``pattern`` area-averaged onto the camera frame scaled to ``frame_size`` (width, height), cut
    to ``box`` (x, y, width, height in that scaled frame): float32 (height, width) of the box.

    Why: touch may read the light on a coarser grid than the camera's (``detect_scale`` < 1). The probe's light is
    linear in its pattern, so ``1 + level * pattern_on_grid(...)`` is the camera-size light averaged over each
    coarse pixel, the cells' edges blended as the camera's pixels blend them."""
    scaled = pattern if (pattern.shape[1], pattern.shape[0]) == tuple(frame_size) else cv2.resize(
        pattern, tuple(frame_size), interpolation=cv2.INTER_AREA
    )
    x, y, w, h = box
    return np.ascontiguousarray(scaled[y : y + h, x : x + w], dtype=np.float32)


def probe_level(t: float, amplitude: float = AMPLITUDE, period_s: float = PERIOD_S) -> float:
    """The modulation's signed depth at time ``t``: multiply the pattern by it and add 1."""
    return amplitude * math.sin(2.0 * math.pi * t / period_s)


def probe_light(t: float, pattern: np.ndarray, amplitude: float = AMPLITUDE) -> np.ndarray:
    """The probe's light relative to flat grey at ``t`` (H, W) float32."""
    return light_at(probe_level(t, amplitude), pattern)


def light_at(level: float, pattern: np.ndarray) -> np.ndarray:
    """``1 + level * pattern`` (H, W) float32: the probe's light at one (exposure-mixed) level."""
    return (1.0 + np.float32(level) * pattern).astype(np.float32)


class ProbeLevels:
    """The probe's level of each frame the projector showed, with when it was shown; mixed over a camera exposure.

    Fed on the event loop (``hub.projector_probe``), read from the camera's or the pipeline's thread: appends and
    snapshots of a deque are safe across threads. ``None`` is a frame without the probe (mixed as level 0)."""

    def __init__(self, window_s: float = 1.0, keep: int = 128) -> None:
        """``window_s``: how far back an exposure being processed can reach (older levels are dropped)."""
        self._window = window_s
        self._shown: deque[tuple[float, float | None]] = deque(maxlen=keep)

    def record(self, t: float, level: float | None) -> None:
        """The frame shown at ``t`` (the daemon's clock) carried the probe at ``level``; times must increase."""
        if self._shown and t <= self._shown[-1][0]:
            return
        self._shown.append((t, None if level is None else float(level)))
        while len(self._shown) > 1 and self._shown[1][0] <= t - self._window:
            self._shown.popleft()

    def level(self, t: float, exposure_s: float, latency_s: float) -> float | None:
        """The probe's level the camera exposure centred on ``t`` integrated, or None before any frame was shown.

        Frame ``i`` lights the membrane from ``shown[i] + latency`` until the next one's; the exposure mixes them by
        overlap (a zero exposure takes the frame lit at its centre). The oldest level stands for any earlier time."""
        shown = list(self._shown)
        if not shown:
            return None
        start = t - exposure_s / 2.0 - latency_s
        instant = exposure_s <= 1e-9  # shorter than any shutter: the frame lit at the centre (no float underflow)
        end = start + max(exposure_s, 0.0)
        total = 0.0
        for i, (at, level) in enumerate(shown):
            lo = -math.inf if i == 0 else at
            hi = math.inf if i + 1 == len(shown) else shown[i + 1][0]
            if instant:
                if lo <= start < hi:
                    return level or 0.0
                continue
            overlap = min(end, hi) - max(start, lo)
            if overlap > 0.0 and level is not None:
                total += level * overlap / exposure_s
        return total

    def active(self) -> bool:
        """Whether the newest frame shown carries the probe (the touch side then passes its light)."""
        shown = list(self._shown)
        return bool(shown) and shown[-1][1] is not None
