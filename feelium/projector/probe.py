"""The probe: a faint, slow pattern the projector can lay over a static skin so touch can tell room light from its own.

On a skin that shows nothing changing (no one inside, a still avatar) the
camera cannot tell the projector's light from the room's, and in a lit room
that is what separates a contact from a hover (:mod:`feelium.touch.roomshare`).
The probe modulates the projected light by ``1 + amplitude * s(x, y) * sin(2 pi t / period)``
with ``s`` a checkerboard of +-1 cells: half the skin brightens while the other
half dims, so the skin's mean (what the room returns, what an auto-exposure
meters) does not move, and every cell's own light varies by a known amount.

Stated parameters (not fitted to detector scores): 3 % amplitude, a 0.5 s
period, cells of 64 camera pixels (32 mm on the paper's camera scale: a few
coarse tiles of the touch pipeline each, so most tiles lie inside one cell).
The period is short against a hand's approach (a shadow growing under a tile
over a second, while a slow probe happened to rise, read as light following
the projector: with a 2 s period the share came out 0.1 low under one tap and
it was lost) and long against the camera's frame and the projector's latency
(7.5 camera frames per period at 15 fps). Whether a 3 % modulation at 2 Hz is
invisible to a viewer is not measured here.
"""

from __future__ import annotations

import math

import numpy as np

AMPLITUDE = 0.03
PERIOD_S = 0.5
CELL_PX = 64


def probe_pattern(width: int, height: int, cell_px: int = CELL_PX) -> np.ndarray:
    """The checkerboard ``s`` (H, W) float32 of +-1 cells."""
    yy, xx = np.mgrid[0:height, 0:width]
    return np.where(((xx // cell_px) + (yy // cell_px)) % 2 == 0, 1.0, -1.0).astype(np.float32)


def probe_level(t: float, amplitude: float = AMPLITUDE, period_s: float = PERIOD_S) -> float:
    """The modulation's signed depth at time ``t``: multiply the pattern by it and add 1."""
    return amplitude * math.sin(2.0 * math.pi * t / period_s)


def probe_light(t: float, pattern: np.ndarray) -> np.ndarray:
    """The probe's light relative to flat grey at ``t`` (H, W) float32."""
    return (1.0 + np.float32(probe_level(t)) * pattern).astype(np.float32)
