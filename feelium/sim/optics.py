"""The light path inside the envelope, before any hand: back-light and membrane.

The rear camera sees the membrane lit from inside by a laser projector through a
180 degree fisheye. Two static images describe that light path for a session:

- ``B`` (:func:`backlight`): the projector's irradiance on the membrane. A flat
  screen lit by a point-like source falls off with the cosine-fourth law,
  ``1 / (1 + (r / r0)^2)^2`` where ``r0`` is the throw distance in pixels, and
  the fisheye adds a hot spot where its central rays concentrate. Together they
  give a 3:1 to 6:1 ratio across the sensitive patch, as a real fisheye does.
- ``T`` (:func:`membrane_transmission`): what the membrane passes towards the
  camera: a fabric texture (fine weave plus large wrinkles), welded seams that
  cross the patch, and the blackened envelope outside the sensitive patch (ROI).

Over the whole front face (:func:`face_backlight`, a :class:`feelium.skin.face.FaceModel`) the membrane is
the curved envelope: the same lens falloff and hot spot, times the irradiance a point projector at the rear
camera's position gives the sphere, and the envelope is blackened outside the face instead of the ROI.

Laser banding (:func:`laser_banding`) is the one time-varying part of the
projector: a MEMS laser-scanning projector and a rolling-shutter camera beat, so
a faint horizontal stripe pattern drifts down the image.

Everything here is pure: parameters and an RNG in, float32 arrays out.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np

from feelium.skin.face import FaceModel

REFERENCE_WIDTH = 640  # frame width the sessions' pixel lengths (throw, hot spot) are stated for


@dataclass(frozen=True)
class OpticsParams:
    """One session's projector and membrane (all distances in camera pixels)."""

    level: float = 175.0  # camera DN at the brightest ROI point at unit gain, before the shadow
    throw_px: float = 330.0  # r0 of the cosine-fourth falloff: the projector's distance to the membrane
    center_dx: float = 10.0  # offset of the fisheye axis from the frame centre
    center_dy: float = -8.0
    hotspot_gain: float = 0.35  # extra irradiance at the fisheye's hot spot, relative to the axis
    hotspot_sigma: float = 70.0
    hotspot_dx: float = -40.0  # hot spot position relative to the fisheye axis
    hotspot_dy: float = 25.0
    weave_amp: float = 0.025  # fine fabric texture, relative
    wrinkle_amp: float = 0.04  # large-scale wrinkles, relative
    seam_transmission: float = 0.78  # a welded seam passes this much light
    seam_width_px: float = 3.0
    envelope_transmission: float = 0.02  # blackened envelope outside the sensitive patch
    banding_amp: float = 0.03  # laser banding stripe depth, relative
    banding_period_px: float = 37.0
    banding_speed_hz: float = 0.7  # how fast the stripes crawl (stripe periods per second)

    def to_json(self) -> dict[str, float]:
        return asdict(self)


def backlight(params: OpticsParams, width: int, height: int, roi: tuple[int, int, int, int]) -> np.ndarray:
    """Projector irradiance ``B`` on the membrane in camera DN, (H, W) float32.

    Normalised so the brightest point inside the ROI equals ``params.level``.
    """
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    cx = width / 2.0 + params.center_dx
    cy = height / 2.0 + params.center_dy
    r2 = (xs - cx) ** 2 + (ys - cy) ** 2
    cos4 = 1.0 / (1.0 + r2 / params.throw_px**2) ** 2
    hx, hy = cx + params.hotspot_dx, cy + params.hotspot_dy
    hot = params.hotspot_gain * np.exp(-((xs - hx) ** 2 + (ys - hy) ** 2) / (2.0 * params.hotspot_sigma**2))
    b = cos4 * (1.0 + hot)
    x, y, w, h = roi
    b *= params.level / float(b[y : y + h, x : x + w].max())
    return b.astype(np.float32)


def face_backlight(params: OpticsParams, face: FaceModel) -> np.ndarray:
    """Projector irradiance ``B`` over the whole curved face in camera DN, (H, W) float32.

    Two stated factors. The lens: the session's falloff and hot spot
    (:func:`backlight`'s formula), with its pixel lengths scaled from a
    :data:`REFERENCE_WIDTH` frame to this one, so a session's unevenness means
    the same share of the image. The envelope: a point projector on the axis at
    the rear camera's position (the two sit together at the rear), whose
    equidistant fisheye spreads uniform pixels over solid angle as
    ``theta / sin(theta)``, lighting the sphere at distance ``d`` and incidence
    ``i``: ``theta / sin(theta) * cos(i) / d^2``. Normalised so the brightest
    point on the face equals ``params.level``.
    """
    width, height = face.width, face.height
    k = width / REFERENCE_WIDTH
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    cx = width / 2.0 + params.center_dx * k
    cy = height / 2.0 + params.center_dy * k
    cos4 = 1.0 / (1.0 + ((xs - cx) ** 2 + (ys - cy) ** 2) / (params.throw_px * k) ** 2) ** 2
    hx, hy = cx + params.hotspot_dx * k, cy + params.hotspot_dy * k
    hot = params.hotspot_gain * np.exp(-((xs - hx) ** 2 + (ys - hy) ** 2) / (2.0 * (params.hotspot_sigma * k) ** 2))
    # The envelope point each pixel sees, from the camera (= the projector), and the sphere's normal there.
    u, v = face.to_uv(xs, ys)
    px, py, pz = face.surface(np.nan_to_num(u, nan=0.5), np.nan_to_num(v, nan=0.5))
    dist = np.sqrt(px * px + py * py + pz * pz)
    theta = np.arccos(np.clip(pz / dist, -1.0, 1.0))
    spread = np.where(theta > 1e-9, theta / np.maximum(np.sin(theta), 1e-12), 1.0)
    normal_z = (pz - face.camera_behind_mm) / face.radius_mm  # outward normal (P - centre) / R
    incidence = (px * px + py * py) / (dist * face.radius_mm) + pz * normal_z / dist
    b = cos4 * (1.0 + hot) * spread * np.clip(incidence, 0.0, 1.0) / (dist * dist)
    b *= params.level / float(b[face.mask()].max())
    return b.astype(np.float32)


def membrane_transmission(
    params: OpticsParams,
    width: int,
    height: int,
    roi: tuple[int, int, int, int],
    rng: np.random.Generator,
    *,
    face: np.ndarray | None = None,
) -> np.ndarray:
    """Membrane transmission ``T`` (H, W) float32: texture and seams in the ROI, black envelope outside.

    ``face`` (bool (H, W)): the light-scattering front face; the envelope is blackened outside it instead of
    outside the ROI rectangle.
    """
    weave = cv2.GaussianBlur(rng.standard_normal((height, width)).astype(np.float32), (0, 0), 1.2)
    weave /= max(float(weave.std()), 1e-6)
    coarse = rng.standard_normal((height // 16 + 2, width // 16 + 2)).astype(np.float32)
    wrinkles = cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC)
    wrinkles = cv2.GaussianBlur(wrinkles, (0, 0), 12.0)
    wrinkles /= max(float(wrinkles.std()), 1e-6)
    t = 1.0 + params.weave_amp * weave + params.wrinkle_amp * wrinkles

    x, y, w, h = roi
    seams = np.ones((height, width), np.float32)
    seam_x = x + int(rng.uniform(0.3, 0.7) * w)  # one vertical and one gently slanted horizontal weld
    seam_y0 = y + rng.uniform(0.25, 0.75) * h
    slope = rng.uniform(-0.04, 0.04)
    thickness = max(1, int(round(params.seam_width_px)))
    cv2.line(seams, (seam_x, 0), (seam_x + int(rng.integers(-6, 7)), height - 1), params.seam_transmission, thickness)
    cv2.line(
        seams, (0, int(seam_y0)), (width - 1, int(seam_y0 + slope * width)), params.seam_transmission, thickness
    )
    seams = cv2.GaussianBlur(seams, (0, 0), 0.8)
    t *= seams

    patch = np.zeros((height, width), np.float32)
    if face is None:
        patch[y : y + h, x : x + w] = 1.0
    else:
        patch[face] = 1.0
    patch = cv2.GaussianBlur(patch, (0, 0), 1.5)
    t = t * (params.envelope_transmission + (1.0 - params.envelope_transmission) * patch)
    return np.clip(t, 0.0, None).astype(np.float32)


def laser_banding(params: OpticsParams, height: int, t: float) -> np.ndarray:
    """Multiplicative stripe factor (H, 1) float32 at camera time ``t``: 1 +/- ``banding_amp``."""
    rows = np.arange(height, dtype=np.float32)
    phase = 2.0 * np.pi * (rows / params.banding_period_px + params.banding_speed_hz * t)
    return (1.0 + params.banding_amp * np.sin(phase)).astype(np.float32)[:, None]


def roi_ratio(b: np.ndarray, roi: tuple[int, int, int, int]) -> float:
    """Brightest over darkest back-light inside the ROI (the unevenness the detector must absorb)."""
    x, y, w, h = roi
    patch = b[y : y + h, x : x + w]
    return float(patch.max() / max(float(patch.min()), 1e-9))
