"""The whole front face: where a camera pixel lies on the curved envelope, and back.

The paper's "sensitive patch" was one rectangle in camera pixels; the blimp is
touched anywhere on its front. This module is the geometric model that makes
that a place on the envelope instead of a place in the image (see
``docs/touch.md``, "The whole front face"):

- the envelope is a sphere of ``radius_mm`` (the 64 cm blimp: 320 mm);
- the rear camera sits on the blimp's front axis, ``camera_behind_mm`` behind
  the sphere's centre, looking forward through an equidistant fisheye
  (``r = focal_px * theta``, ``theta`` the angle off the optical axis);
- skin ``(u, v)`` is azimuth and elevation on the envelope seen from the
  sphere's centre, over the face's angular extent and centred on the front
  axis: azimuth ``(u - 0.5) * azimuth_deg``, elevation ``(0.5 - v) *
  elevation_deg``, direction ``(sin az cos el, -sin el, cos az cos el)`` in
  camera axes (x right, y down, z forward). That is exactly the browser
  client's assumption (``docs/api.md``, 100 x 75 degrees), so a touch's u, v
  means the same spot to the headset, whatever camera or lens saw it.

Pure numpy: arrays in, arrays out; every function takes scalars or arrays of
any shape. Camera pixel centres are on integers (OpenCV's convention).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import cached_property
from typing import Any

import numpy as np

ArrayLike = float | np.ndarray
FIELDS = ("width", "height", "focal_px", "cx", "cy", "radius_mm", "camera_behind_mm", "azimuth_deg", "elevation_deg")
_DIFF = 1e-4  # step in u, v for the local scale (finite differences)
# The front face spans these degrees of azimuth and elevation around the front axis (skin u, v = 0..1 across
# them). An assumption of the envelope's geometry (the face centred on the front camera's axis), stated, not
# measured: the browser client and GET /lens (``skin_patch_deg``) place touches in the fisheye view with it.
FACE_AZIMUTH_DEG = 100.0
FACE_ELEVATION_DEG = 75.0


@dataclass(frozen=True)
class FaceModel:
    """The front face as the rear camera sees it (lengths in mm, pixels of a ``width x height`` frame)."""

    width: int
    height: int
    focal_px: float  # equidistant fisheye: pixels per radian off the optical axis
    cx: float
    cy: float
    radius_mm: float = 320.0  # 64 cm envelope
    camera_behind_mm: float = 240.0  # the rear camera on the front axis, this far behind the centre
    azimuth_deg: float = FACE_AZIMUTH_DEG  # the face's extent, served to headsets in GET /lens
    elevation_deg: float = FACE_ELEVATION_DEG

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"face: frame size must be positive, got {self.width}x{self.height}")
        if not (self.focal_px > 0 and self.radius_mm > 0):
            raise ValueError("face: focal_px and radius_mm must be positive")
        if not (0.0 <= self.camera_behind_mm < self.radius_mm):
            raise ValueError(f"face: camera_behind_mm must be in [0, radius_mm), got {self.camera_behind_mm}")
        if not (0 < self.azimuth_deg < 180 and 0 < self.elevation_deg < 180):
            raise ValueError("face: azimuth_deg and elevation_deg must be in (0, 180)")

    @classmethod
    def for_frame(cls, width: int, height: int, *, fill: float = 0.97, **geometry: float) -> "FaceModel":
        """The lens that fills a ``width x height`` frame with the face (``fill`` of each half-size), centred.

        The rear camera's lens is chosen for the face, as the projector's is:
        a wider one wastes pixels on the black envelope, a narrower one cuts
        the face's rim.
        """
        unit = cls(width, height, 1.0, 0.0, 0.0, **geometry)  # type: ignore[arg-type]
        edge = np.linspace(0.0, 1.0, 201)
        us = np.concatenate([edge, edge, np.zeros_like(edge), np.ones_like(edge)])
        vs = np.concatenate([np.zeros_like(edge), np.ones_like(edge), edge, edge])
        x, y = unit.to_camera(us, vs)
        focal = min(fill * width / 2.0 / float(np.abs(x).max()), fill * height / 2.0 / float(np.abs(y).max()))
        return cls(width, height, focal, (width - 1) / 2.0, (height - 1) / 2.0, **geometry)  # type: ignore[arg-type]

    # --- u, v on the envelope <-> camera pixels -------------------------------------------------

    def surface(self, u: ArrayLike, v: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The envelope point at skin ``(u, v)`` in mm, camera axes, origin at the camera."""
        az = np.radians((np.asarray(u, float) - 0.5) * self.azimuth_deg)
        el = np.radians((0.5 - np.asarray(v, float)) * self.elevation_deg)
        r = self.radius_mm
        return r * np.sin(az) * np.cos(el), -r * np.sin(el), r * np.cos(az) * np.cos(el) + self.camera_behind_mm

    def to_camera(self, u: ArrayLike, v: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Camera pixel ``(x, y)`` of skin ``(u, v)`` (the equidistant fisheye of the envelope point)."""
        px, py, pz = self.surface(u, v)
        rho = np.hypot(px, py)
        theta = np.arctan2(rho, pz)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = np.where(rho > 1e-12, theta / np.maximum(rho, 1e-300), 1.0 / pz)  # theta / rho -> 1 / z on the axis
        return self.cx + self.focal_px * k * px, self.cy + self.focal_px * k * py

    def to_uv(self, x: ArrayLike, y: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Skin ``(u, v)`` seen at camera pixel ``(x, y)``: the view ray met with the envelope (NaN beyond 180 deg).

        The camera is inside the sphere, so every ray meets it exactly once in
        front of the camera; ``(u, v)`` outside ``[0, 1)`` is the envelope off
        the face.
        """
        dx, dy = np.asarray(x, float) - self.cx, np.asarray(y, float) - self.cy
        r = np.hypot(dx, dy)
        theta = r / self.focal_px
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(r > 1e-12, np.sin(theta) / np.maximum(r, 1e-300), 1.0 / self.focal_px)
        wx, wy, wz = s * dx, s * dy, np.cos(theta)
        c, big_r = self.camera_behind_mm, self.radius_mm
        along = c * wz + np.sqrt(c * c * wz * wz - c * c + big_r * big_r)  # positive root of |o + s w| = R
        qx, qy, qz = along * wx, along * wy, along * wz - c  # from the centre
        el = np.arcsin(np.clip(-qy / big_r, -1.0, 1.0))
        az = np.arctan2(qx, qz)
        u = 0.5 + np.degrees(az) / self.azimuth_deg
        v = 0.5 - np.degrees(el) / self.elevation_deg
        beyond = theta > math.pi / 2
        return np.where(beyond, np.nan, u), np.where(beyond, np.nan, v)

    # --- what the pipeline and the simulator need -----------------------------------------------

    def mask(self) -> np.ndarray:
        """The face on the camera frame, (height, width) bool, read-only: pixel centres whose ``(u, v)`` lie in
        ``[0, 1)``. Computed once per model (a megapixel frame takes a second)."""
        return self._mask

    @cached_property
    def _mask(self) -> np.ndarray:
        ys, xs = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        u, v = self.to_uv(xs, ys)
        with np.errstate(invalid="ignore"):
            mask = (u >= 0.0) & (u < 1.0) & (v >= 0.0) & (v < 1.0)
        mask.setflags(write=False)
        return mask

    def distance_mm(self, u0: ArrayLike, v0: ArrayLike, u1: ArrayLike, v1: ArrayLike) -> np.ndarray:
        """Distance on the membrane between two skin points (mm along the envelope: the great circle)."""
        a = np.stack(self.surface(u0, v0))
        b = np.stack(self.surface(u1, v1))
        a[2] -= self.camera_behind_mm  # from the centre
        b[2] -= self.camera_behind_mm
        cross = np.linalg.norm(np.cross(a, b, axis=0), axis=0)
        return self.radius_mm * np.arctan2(cross, np.sum(a * b, axis=0))

    def roi(self) -> tuple[int, int, int, int]:
        """The face's bounding box ``[x, y, w, h]`` in camera pixels: the ROI the working resolution is cut from."""
        m = self.mask()
        rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
        if rows.size == 0:
            raise ValueError("face: the face is not on the camera frame")
        return int(cols[0]), int(rows[0]), int(cols[-1] - cols[0] + 1), int(rows[-1] - rows[0] + 1)

    def px_per_mm(self, u: ArrayLike, v: ArrayLike) -> np.ndarray:
        """Local scale at skin ``(u, v)``: camera pixels per mm on the membrane (square root of the area ratio).

        The fisheye and the envelope's slope away from the camera compress the
        image towards the rim; this is the one number a hand's size in pixels
        needs there (the compression is stronger radially than across, which
        a single scale averages).
        """
        u, v = np.asarray(u, float), np.asarray(v, float)
        xu1, yu1 = self.to_camera(u + _DIFF, v)
        xu0, yu0 = self.to_camera(u - _DIFF, v)
        xv1, yv1 = self.to_camera(u, v + _DIFF)
        xv0, yv0 = self.to_camera(u, v - _DIFF)
        det = np.abs((xu1 - xu0) * (yv1 - yv0) - (xv1 - xv0) * (yu1 - yu0)) / (2 * _DIFF) ** 2
        el = np.radians((0.5 - v) * self.elevation_deg)
        mm_u = self.radius_mm * np.cos(el) * math.radians(self.azimuth_deg)  # arc length per unit u
        mm_v = self.radius_mm * math.radians(self.elevation_deg)
        return np.sqrt(det / (mm_u * mm_v))

    # --- recordings ---------------------------------------------------------------------------

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, obj: Any) -> "FaceModel":
        """From a recording's ``meta["face"]`` (or the config); ``ValueError`` names what is wrong."""
        if not isinstance(obj, dict):
            raise ValueError(f"face: expected an object, got {type(obj).__name__}")
        unknown = sorted(set(obj) - set(FIELDS))
        if unknown:
            raise ValueError(f"face: unknown key {unknown[0]!r}")
        for key in FIELDS[:5]:
            if key not in obj:
                raise ValueError(f"face: missing {key!r}")
        values: dict[str, Any] = {}
        for key, raw in obj.items():
            if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
                raise ValueError(f"face: {key} must be a finite number, got {raw!r}")
            values[key] = int(raw) if key in ("width", "height") else float(raw)
        return cls(**values)
