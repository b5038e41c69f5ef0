"""Structured-light patterns and their decoding: Gray code for the block, phase shift inside it.

Through the fisheye a projector pixel is smaller than a camera pixel, so the
finest Gray-code stripes blur away before the camera sees them. The Gray code
(OpenCV contrib's ``cv2.structured_light.GrayCodePattern``, each pattern
followed by its inverse) therefore only resolves blocks of ``block`` projector
pixels; ``steps`` phase-shifted cosine fringes of period ``period`` then place
each camera pixel inside its block to a fraction of a pixel. With 8 steps the
projector's gamma (which adds harmonics to the fringes) cancels out. A local
first-order fit over covered neighbours smooths the decoded map without
biasing it at the patch's border.

Pure: projector size and parameters in, pattern images out; captured float
images in, maps out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np


GREY_LEVELS = (64, 128, 192)  # flat greys for the photometric fit (black level and gamma)


@dataclass(frozen=True)
class Pattern:
    """One projector image of the sequence and what it encodes."""

    name: str  # "white", "black", "gray_x3", "gray_x3_inv", "phase_y5", ...
    image: np.ndarray  # (H_p, W_p) uint8


@dataclass(frozen=True)
class PatternPlan:
    """The sizes the sequence was made for (the decoder needs the same)."""

    width: int
    height: int
    block: int
    period: int
    steps: int

    @property
    def blocks(self) -> tuple[int, int]:
        return math.ceil(self.width / self.block), math.ceil(self.height / self.block)

    @property
    def bits(self) -> tuple[int, int]:
        bw, bh = self.blocks
        return max(1, math.ceil(math.log2(bw))), max(1, math.ceil(math.log2(bh)))


def make_patterns(plan: PatternPlan) -> list[Pattern]:
    """White, black, flat greys, Gray-code pairs (x then y, most significant bit first) and phase fringes (x then y)."""
    if plan.period < 2 * plan.block:
        raise ValueError(f"phase period {plan.period} must be at least twice the Gray block {plan.block}")
    bw, bh = plan.blocks
    gray = cv2.structured_light.GrayCodePattern.create(width=bw, height=bh)
    ok, coarse = gray.generate()
    if not ok:
        raise RuntimeError("cv2.structured_light could not generate Gray-code patterns")
    nx, ny = plan.bits
    if len(coarse) != 2 * (nx + ny):
        raise RuntimeError(f"expected {2 * (nx + ny)} Gray-code images, OpenCV made {len(coarse)}")
    w, h = plan.width, plan.height
    patterns = [Pattern("white", np.full((h, w), 255, np.uint8)), Pattern("black", np.zeros((h, w), np.uint8))]
    patterns += [Pattern(f"level_{v}", np.full((h, w), v, np.uint8)) for v in GREY_LEVELS]
    for i, img in enumerate(coarse):
        axis, bit = ("x", i // 2) if i < 2 * nx else ("y", (i - 2 * nx) // 2)
        full = np.repeat(np.repeat(img, plan.block, axis=0), plan.block, axis=1)[:h, :w]
        patterns.append(Pattern(f"gray_{axis}{bit}" + ("_inv" if i % 2 else ""), np.ascontiguousarray(full)))
    xs = np.arange(w, dtype=np.float64)
    ys = np.arange(h, dtype=np.float64)
    for axis, coords, shape in (("x", xs[None, :], (h, w)), ("y", ys[:, None], (h, w))):
        for k in range(plan.steps):
            delta = 2 * math.pi * k / plan.steps
            wave = 0.5 + 0.5 * np.cos(2 * math.pi * coords / plan.period - delta)
            img = np.broadcast_to(np.rint(255 * wave).astype(np.uint8), shape)
            patterns.append(Pattern(f"phase_{axis}{k}", np.ascontiguousarray(img)))
    return patterns


@dataclass(frozen=True)
class Decoded:
    """Per-camera-pixel decoding before smoothing."""

    proj_x: np.ndarray  # (H, W) float32, NaN where invalid
    proj_y: np.ndarray
    valid: np.ndarray  # (H, W) bool
    contrast: np.ndarray  # (H, W) float32 white minus black


def _gray_index(captures: dict[str, np.ndarray], axis: str, nbits: int) -> np.ndarray:
    """Block index from the Gray-code pairs (bit = pattern brighter than its inverse)."""
    binary = None
    index = None
    for bit in range(nbits):
        g = captures[f"gray_{axis}{bit}"] > captures[f"gray_{axis}{bit}_inv"]
        binary = g if binary is None else np.logical_xor(binary, g)
        index = binary.astype(np.int32) if index is None else (index << 1) | binary
    assert index is not None
    return index


def _phase(captures: dict[str, np.ndarray], axis: str, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Fringe phase (0..2pi) and modulation amplitude per pixel."""
    s = np.zeros_like(captures[f"phase_{axis}0"], dtype=np.float32)
    c = np.zeros_like(s)
    for k in range(steps):
        delta = 2 * math.pi * k / steps
        img = captures[f"phase_{axis}{k}"]
        s += img * np.float32(math.sin(delta))
        c += img * np.float32(math.cos(delta))
    phase = np.mod(np.arctan2(s, c), 2 * math.pi).astype(np.float32)
    amplitude = (2.0 / steps) * np.hypot(s, c)
    return phase, amplitude.astype(np.float32)


def decode(captures: dict[str, np.ndarray], plan: PatternPlan, min_contrast: float) -> Decoded:
    """Decode captured camera images (float32, keyed by pattern name) into a raw camera-to-projector map."""
    white, black = captures["white"], captures["black"]
    contrast = (white - black).astype(np.float32)
    valid = contrast >= min_contrast
    nx, ny = plan.bits
    out = []
    for axis, nbits, limit in (("x", nx, plan.width), ("y", ny, plan.height)):
        block_index = _gray_index(captures, axis, nbits)
        coarse = block_index * plan.block + (plan.block - 1) / 2.0
        phase, amplitude = _phase(captures, axis, plan.steps)
        fine = phase * (plan.period / (2 * math.pi))
        pos = fine + plan.period * np.rint((coarse - fine) / plan.period)
        # A pixel is trusted when the fringe is visible and Gray code and phase agree
        # (off by at most one block plus half a block at a block boundary).
        valid &= amplitude >= 0.15 * contrast
        valid &= np.abs(pos - coarse) <= 1.5 * plan.block
        valid &= (pos >= -0.5) & (pos <= limit - 0.5)
        out.append(pos.astype(np.float32))
    proj_x, proj_y = out
    proj_x[~valid] = np.nan
    proj_y[~valid] = np.nan
    return Decoded(proj_x, proj_y, valid, contrast)


def smooth_map(values: np.ndarray, valid: np.ndarray, sigma: float) -> np.ndarray:
    """Local first-order (plane) fit of ``values`` over valid pixels in a Gaussian window.

    Unlike a plain masked blur, a plane fit has no bias where the window is
    cut by the patch's border, which matters for a map whose gradient is
    nearly 2 projector px per camera px.
    """
    if sigma <= 0:
        out = values.astype(np.float32).copy()
        out[~valid] = np.nan
        return out
    radius = max(1, int(math.ceil(3 * sigma)))
    offs = np.arange(-radius, radius + 1, dtype=np.float64)
    g = np.exp(-0.5 * (offs / sigma) ** 2)
    k0, k1, k2 = g, g * offs, g * offs**2
    m = valid.astype(np.float64)
    v = np.where(valid, values, 0.0).astype(np.float64)

    def conv(src: np.ndarray, kx: np.ndarray, ky: np.ndarray) -> np.ndarray:
        return cv2.sepFilter2D(src, cv2.CV_64F, kx, ky, borderType=cv2.BORDER_CONSTANT)

    s0, sx, sy = conv(m, k0, k0), conv(m, k1, k0), conv(m, k0, k1)
    sxx, sxy, syy = conv(m, k2, k0), conv(m, k1, k1), conv(m, k0, k2)
    t0, tx, ty = conv(v, k0, k0), conv(v, k1, k0), conv(v, k0, k1)
    # Solve [[s0 sx sy] [sx sxx sxy] [sy sxy syy]] [a b c]^T = [t0 tx ty]^T for a (Cramer's rule).
    det = s0 * (sxx * syy - sxy * sxy) - sx * (sx * syy - sxy * sy) + sy * (sx * sxy - sxx * sy)
    num = t0 * (sxx * syy - sxy * sxy) - sx * (tx * syy - sxy * ty) + sy * (tx * sxy - sxx * ty)
    scale = s0**3 + 1e-30
    ok = valid & (np.abs(det) > 1e-9 * scale)
    out = np.full(values.shape, np.nan, np.float32)
    out[ok] = (num[ok] / det[ok]).astype(np.float32)
    return out


def photometric(captures: dict[str, np.ndarray], valid: np.ndarray) -> tuple[float, float]:
    """Projector black level (relative to white) and gamma, from this sequence's flat captures over valid pixels."""
    greys = {v: captures[f"level_{v}"] for v in GREY_LEVELS}
    black_level, gamma = flat_response(captures["white"], captures["black"], greys, valid)
    if gamma is None:
        raise ValueError("grey-level captures are not brighter than black; cannot fit gamma")
    return black_level, gamma


def flat_response(
    white: np.ndarray, black: np.ndarray, greys: dict[int, np.ndarray], valid: np.ndarray
) -> tuple[float, float | None]:
    """Black level (relative to white) and gamma from camera images of flat projector frames.

    The camera sees ``k * (black + (1 - black) * (v / 255) ^ gamma)`` for grey ``v``;
    the dark frame includes the room light, so the black level measured here
    is an upper bound, which is what the back-light prediction needs anyway
    (the room light does not change with the projected content). Gamma needs
    at least two greys strictly between black and white (``None`` otherwise):
    one grey fits any curve through the origin of the log-log line exactly, so
    it would be a guess with no residual to judge it by.
    """
    white_v = white[valid].astype(np.float64)
    black_v = black[valid].astype(np.float64)
    ok = white_v > black_v + 1.0
    white_v, black_v = white_v[ok], black_v[ok]
    if white_v.size < 10:
        raise ValueError("too few lit pixels to measure the projector's black level and gamma")
    black_level = float(np.median(black_v / white_v))
    xs, ys = [], []
    for v, image in sorted(greys.items()):
        if not 0 < v < 255:
            continue
        grey = image[valid].astype(np.float64)[ok]
        rel = float(np.median((grey - black_v) / (white_v - black_v)))
        if rel > 0:
            xs.append(math.log(v / 255.0))
            ys.append(math.log(rel))
    if len(xs) < 2:
        return black_level, None
    gamma = float(np.dot(xs, ys) / np.dot(xs, xs))  # a line through the origin: log rel = gamma * log level
    return black_level, gamma
