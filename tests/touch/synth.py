"""Synthetic rear-camera frames for unit tests: uneven back-light, noise, shadows.

Deliberately simple and independent of the scene simulator (feelium.sim), so
the pipeline's unit tests do not depend on one generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

W, H = 160, 120
ROI = (16, 12, 128, 96)


def backlight(width: int = W, height: int = H, ratio: float = 3.0) -> np.ndarray:
    """A back-light falling off ``ratio``:1 from the centre to the corners (float32 grey levels)."""
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    r2 = ((xs - width / 2) / (width / 2)) ** 2 + ((ys - height / 2) / (height / 2)) ** 2
    falloff = 1.0 / (1.0 + (ratio - 1.0) * r2 / 2.0)
    return (200.0 * falloff).astype(np.float32)


@dataclass(frozen=True)
class Blob:
    """A gaussian shadow: ``depth`` is the fraction of light lost at its centre."""

    x: float
    y: float
    depth: float
    sigma: float = 4.0


@dataclass(frozen=True)
class Patch:
    """Skin pressed on the membrane: a disc of ``depth`` with an edge blurred only by ``edge_sigma`` px."""

    x: float
    y: float
    depth: float
    radius: float
    edge_sigma: float = 1.0

    def loss(self, width: int, height: int) -> np.ndarray:
        ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
        inside = (((xs - self.x) ** 2 + (ys - self.y) ** 2) <= self.radius**2).astype(np.float32)
        return self.depth * cv2.GaussianBlur(inside, (0, 0), self.edge_sigma)


def render(
    light: np.ndarray,
    blobs: list[Blob | Patch] = (),  # type: ignore[assignment]
    *,
    gain: float = 1.0,
    noise: float = 2.0,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """One uint8 frame: back-light times exposure gain, darkened by the blobs, plus sensor noise."""
    height, width = light.shape
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    img = light * np.float32(gain)
    for b in blobs:
        if isinstance(b, Patch):
            img = img * (1.0 - b.loss(width, height))
        else:
            img = img * (1.0 - b.depth * np.exp(-((xs - b.x) ** 2 + (ys - b.y) ** 2) / (2 * b.sigma**2)))
    if noise > 0:
        rng = rng or np.random.default_rng(0)
        img = img + rng.normal(0.0, noise, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
