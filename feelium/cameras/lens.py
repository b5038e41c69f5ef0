"""The front fisheye's lens model, as the headset receives it at ``GET /lens``.

The model is OpenCV's fisheye model (``cv2.fisheye``, Kannala-Brandt with four
coefficients): a direction at angle ``theta`` off the optical axis lands at
radius ``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)``
(in units of the focal length) from the principal point. Chosen because the
same four numbers are what ``cv2.fisheye.calibrate`` fits and what the headset
needs, and the equations are short enough to port to Swift or JavaScript
(``docs/visionos.md``). :func:`project` and :func:`unproject` are those
equations in numpy, the reference the ports are checked against.

Camera axes are OpenCV's: ``x`` right, ``y`` down, ``z`` forward along the
optical axis; pixel centres sit on integers.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

MODEL = "opencv_fisheye"
SOURCES = ("sim", "calibrated", "nominal")
NEWTON_STEPS = 12


class LensError(ValueError):
    """A lens file or JSON that cannot be used; names what is wrong."""


@dataclass(frozen=True)
class FisheyeLens:
    """Intrinsics ``fx, fy, cx, cy`` (pixels, no skew) and distortion ``d = (k1, k2, k3, k4)`` at ``width x height``.

    ``source`` says where the numbers came from (``sim``: the simulator's exact lens; ``calibrated``: fitted by
    ``feelium calibrate lens`` with RMS reprojection error ``rms_px``; ``nominal``: an uncalibrated stand-in).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    d: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    source: str = "nominal"
    rms_px: float | None = None

    @property
    def K(self) -> np.ndarray:  # noqa: N802 - OpenCV's name
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def D(self) -> np.ndarray:  # noqa: N802 - OpenCV's name
        return np.array(self.d, dtype=np.float64).reshape(4, 1)

    def to_json(self) -> dict[str, Any]:
        """What ``GET /lens`` answers and the lens file holds: ``K`` and ``D`` as ``cv2.fisheye`` takes them."""
        return {
            "model": MODEL,
            "width": self.width,
            "height": self.height,
            "K": [[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]],
            "D": list(self.d),
            "source": self.source,
            "rms_px": self.rms_px,
        }

    @classmethod
    def from_json(cls, data: Any) -> "FisheyeLens":
        """The lens of a :meth:`to_json` dict; :class:`LensError` naming the first thing wrong."""
        if not isinstance(data, dict) or data.get("model") != MODEL:
            raise LensError(f"not an {MODEL} lens (model: {data.get('model') if isinstance(data, dict) else data!r})")
        try:
            width, height = int(data["width"]), int(data["height"])
            k = [[float(v) for v in row] for row in data["K"]]
            d = tuple(float(v) for v in data["D"])
            rms = data.get("rms_px")
            rms_px = None if rms is None else float(rms)
            source = str(data.get("source", "calibrated"))
        except (KeyError, TypeError, ValueError) as exc:
            raise LensError(f"lens field missing or not a number: {exc}") from None
        if len(k) != 3 or any(len(row) != 3 for row in k) or len(d) != 4:
            raise LensError("K must be 3x3 and D must have 4 coefficients (k1..k4)")
        if k[0][1] != 0.0 or k[1][0] != 0.0 or k[2] != [0.0, 0.0, 1.0]:
            raise LensError("K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)")
        values = [k[0][0], k[1][1], k[0][2], k[1][2], *d]
        if not all(math.isfinite(v) for v in values) or k[0][0] <= 0 or k[1][1] <= 0 or width <= 0 or height <= 0:
            raise LensError("focal lengths and the image size must be positive and every number finite")
        if source not in SOURCES:
            raise LensError(f"source must be one of {', '.join(SOURCES)}, got {source!r}")
        return cls(width, height, k[0][0], k[1][1], k[0][2], k[1][2], d, source, rms_px)  # type: ignore[arg-type]

    def scaled(self, width: int, height: int) -> "FisheyeLens":
        """The same lens for frames resized to ``width x height`` (the same sensor area, only resampled).

        Focal lengths scale with the image; the principal point scales about the pixel *edges* (pixel
        centres sit on integers); ``D`` works on angles and does not change. :class:`LensError` when the
        aspect ratio differs, since then the frames were cropped and the model cannot be carried over.
        """
        if (width, height) == (self.width, self.height):
            return self
        sx, sy = width / self.width, height / self.height
        if abs(sx - sy) > 0.01 * max(sx, sy):
            raise LensError(
                f"the lens was calibrated at {self.width}x{self.height}, the camera delivers {width}x{height}: "
                "another aspect ratio (a crop) needs its own calibration"
            )
        return replace(
            self, width=width, height=height, fx=self.fx * sx, fy=self.fy * sy,
            cx=(self.cx + 0.5) * sx - 0.5, cy=(self.cy + 0.5) * sy - 0.5,
        )  # fmt: skip


def distort_theta(theta: np.ndarray, d: tuple[float, float, float, float]) -> np.ndarray:
    """``theta_d`` of angles ``theta`` off the axis (radians)."""
    t2 = theta * theta
    k1, k2, k3, k4 = d
    return theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))


def undistort_theta(theta_d: np.ndarray, d: tuple[float, float, float, float]) -> np.ndarray:
    """The angle ``theta`` whose :func:`distort_theta` is ``theta_d``, by Newton's method from ``theta = theta_d``.

    Converges in a few steps wherever the lens is monotonic (``theta_d`` grows with ``theta``), which is
    everywhere inside a real image circle.
    """
    k1, k2, k3, k4 = d
    theta = np.array(theta_d, dtype=np.float64)
    for _ in range(NEWTON_STEPS):
        t2 = theta * theta
        f = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - theta_d
        df = 1.0 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
        theta = theta - f / df
    return theta


def project(lens: FisheyeLens, points: np.ndarray) -> np.ndarray:
    """Pixels ``(N, 2)`` of camera-frame points or directions ``(N, 3)``.

    ``theta = atan2(hypot(x, y), z)`` rather than OpenCV's ``atan(r / z)``: the same for points in front
    (``z > 0``), and still defined at and beyond 90 degrees off axis, where a wider-than-180-degree lens sees.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    r = np.hypot(p[:, 0], p[:, 1])
    theta_d = distort_theta(np.arctan2(r, p[:, 2]), lens.d)
    scale = np.divide(theta_d, r, out=np.zeros_like(r), where=r > 0)
    return np.stack([lens.fx * p[:, 0] * scale + lens.cx, lens.fy * p[:, 1] * scale + lens.cy], axis=1)


def unproject(lens: FisheyeLens, pixels: np.ndarray) -> np.ndarray:
    """Unit directions ``(N, 3)`` in the camera frame seen at pixels ``(N, 2)``: the inverse of :func:`project`."""
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    a = (px[:, 0] - lens.cx) / lens.fx
    b = (px[:, 1] - lens.cy) / lens.fy
    theta_d = np.hypot(a, b)
    theta = undistort_theta(theta_d, lens.d)
    scale = np.divide(np.sin(theta), theta_d, out=np.ones_like(theta_d), where=theta_d > 0)
    return np.stack([a * scale, b * scale, np.cos(theta)], axis=1)


def load_lens(path: str | Path) -> FisheyeLens:
    """The lens in a JSON lens file (as ``feelium calibrate lens`` writes it); :class:`LensError` names the file."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LensError(f"{path}: cannot read the lens file: {exc}") from None
    try:
        return FisheyeLens.from_json(data)
    except LensError as exc:
        raise LensError(f"{path}: {exc}") from None


def save_lens(lens: FisheyeLens, path: str | Path) -> Path:
    """Write the lens file atomically (temp file, then rename), so a running daemon never reads half of one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temp = path.with_name(f".{path.name}.tmp")
    temp.write_text(json.dumps(lens.to_json(), indent=2) + "\n", encoding="utf-8")
    os.replace(temp, path)
    return path
