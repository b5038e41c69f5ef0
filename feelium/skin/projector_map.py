"""The calibration map: which projector pixel lights the membrane spot each camera pixel sees.

The rear camera and the projector look at the same membrane through different
lenses (the projector through a 180 degree fisheye), so a spot on the skin has
a camera position and a projector position related by a smooth, strongly
non-linear map. Calibration measures it densely, camera to projector (that is
what structured light decodes); the renderer needs the other direction
(projector pixel to skin canvas), which :meth:`ProjectorMap.projector_to_camera`
derives once by a least-squares polynomial fit of the inverse.

Pure: arrays in, arrays out; :func:`load_calibration`/:meth:`save` are the only I/O.
:func:`load_shared` is how the daemon reads the file: one map in memory for every part that uses it.
"""

from __future__ import annotations

import logging
import math
import threading
import weakref
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

Size = tuple[int, int]  # (width, height)
Roi = tuple[int, int, int, int]

DEFAULT_CAMERA_SIZE: Size = (640, 480)  # the rear camera frame the uncalibrated stand-in is drawn for
DEFAULT_ROI: Roi = (64, 48, 512, 384)

log = logging.getLogger(__name__)

_INVERSE_DEGREE = 5
_INVERSE_STEP = 4  # evaluate the inverse on a grid this much coarser, then resize (smooth map; saves memory on a Pi)


class CalibrationError(ValueError):
    """A calibration file or map is unusable: says which and why."""


@dataclass(frozen=True, eq=False)
class ProjectorMap:
    """Dense camera-to-projector map over the sensitive patch.

    ``proj_x``/``proj_y`` are (H, W) float32 at camera resolution: the projector
    pixel (centres at integer coordinates) that lights what camera pixel
    ``(x, y)`` sees; NaN where the calibration did not cover the pixel.
    """

    camera_size: Size
    projector_size: Size
    roi: Roi
    proj_x: np.ndarray
    proj_y: np.ndarray
    source: str = "default"
    black_level: float | None = None  # measured projector black relative to white (None: not measured)
    gamma: float | None = None  # measured projector gamma (None: not measured)
    # Measured projector latency and its spread (s), from a calibration recording (None: not measured; replay and
    # eval then keep [touch] projector_latency_s), :mod:`feelium.lab.projector.latency`.
    latency_s: float | None = None
    latency_sigma_s: float | None = None
    _inverse: list[np.ndarray] = field(default_factory=list, init=False, repr=False)  # see _inverse_fit
    _inverse_lock: threading.Lock = field(default_factory=threading.Lock, init=False, repr=False)

    def __post_init__(self) -> None:
        w, h = self.camera_size
        for name in ("proj_x", "proj_y"):
            arr = getattr(self, name)
            if arr.shape != (h, w):
                raise CalibrationError(f"{name} is {arr.shape}, camera is {(h, w)}")
        x, y, rw, rh = self.roi
        if rw <= 0 or rh <= 0 or x < 0 or y < 0 or x + rw > w or y + rh > h:
            raise CalibrationError(f"roi {self.roi} does not fit the camera frame {self.camera_size}")

    @property
    def covered(self) -> np.ndarray:
        """(H, W) bool: camera pixels with a projector position."""
        return np.isfinite(self.proj_x) & np.isfinite(self.proj_y)

    def coverage(self) -> float:
        """Share of the ROI's pixels the map covers."""
        x, y, w, h = self.roi
        return float(self.covered[y : y + h, x : x + w].mean())

    def to_projector(self, x: float, y: float) -> tuple[float, float] | None:
        """Projector position of camera point ``(x, y)`` (bilinear over covered neighbours); None if uncovered."""
        w, h = self.camera_size
        if not (math.isfinite(x) and math.isfinite(y)) or not (0 <= x <= w - 1 and 0 <= y <= h - 1):
            return None
        x0, y0 = min(int(x), w - 2), min(int(y), h - 2)
        fx, fy = x - x0, y - y0
        weights = np.array([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
        px = self.proj_x[y0 : y0 + 2, x0 : x0 + 2].reshape(-1)
        py = self.proj_y[y0 : y0 + 2, x0 : x0 + 2].reshape(-1)
        ok = np.isfinite(px) & np.isfinite(py) & (weights > 0)
        if not ok.any():
            return None
        wsum = float(weights[ok].sum())
        return float((px[ok] * weights[ok]).sum() / wsum), float((py[ok] * weights[ok]).sum() / wsum)

    def __getstate__(self) -> dict[str, object]:
        """Pickled (a worker process's setup) without the lock, which no process can share."""
        return {key: value for key, value in self.__dict__.items() if key != "_inverse_lock"}

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state, _inverse_lock=threading.Lock())

    def _inverse_fit(self) -> tuple[np.ndarray, np.ndarray]:
        """The inverse polynomial's coefficients for camera x and y, fitted once per map.

        The renderer, both of touch's light predictors and the probe overlay each invert the one shared map at
        start-up. Each fit held a design matrix of every covered camera pixel (~13 MB at 640x480) and its least
        squares' copies, and the fits ran at once in the projector's and touch's threads: the daemon's start-up
        peak stood ~28 MB over its steady resident size (session 25). The 42 coefficients are what is kept."""
        with self._inverse_lock:
            if self._inverse:
                return self._inverse[0], self._inverse[1]
            pw, ph = self.projector_size
            cov = self.covered
            ys, xs = np.nonzero(cov[::2, ::2])
            if len(xs) < 50:
                raise CalibrationError(f"only {int(cov.sum())} covered camera pixels; cannot invert the map")
            cam_x, cam_y = xs * 2.0, ys * 2.0
            px = self.proj_x[ys * 2, xs * 2].astype(np.float64)
            py = self.proj_y[ys * 2, xs * 2].astype(np.float64)
            design = _poly_terms(px / pw, py / ph)
            coef_x, *_ = np.linalg.lstsq(design, cam_x, rcond=None)
            coef_y, *_ = np.linalg.lstsq(design, cam_y, rcond=None)
            self._inverse.extend((coef_x, coef_y))
            return coef_x, coef_y

    def projector_to_camera(self) -> tuple[np.ndarray, np.ndarray]:
        """Inverse map at projector resolution: (H_p, W_p) float32 camera x and y, NaN where not covered.

        A degree-5 polynomial in projector coordinates is fitted by least
        squares to the covered pixels; a projector pixel counts as covered
        when its fitted camera position lands on a covered camera pixel.
        """
        pw, ph = self.projector_size
        cov = self.covered
        coef_x, coef_y = self._inverse_fit()

        gw, gh = pw // _INVERSE_STEP + 2, ph // _INVERSE_STEP + 2
        gx, gy = np.meshgrid(np.arange(gw) * _INVERSE_STEP / pw, np.arange(gh) * _INVERSE_STEP / ph)
        terms = _poly_terms(gx.ravel(), gy.ravel())
        coarse_x = (terms @ coef_x).reshape(gh, gw).astype(np.float32)
        coarse_y = (terms @ coef_y).reshape(gh, gw).astype(np.float32)
        inv_x, inv_y = _upsample_aligned(coarse_x, pw, ph), _upsample_aligned(coarse_y, pw, ph)

        inside = cv2.remap(
            cov.astype(np.uint8), inv_x, inv_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0
        ).astype(bool)
        inv_x[~inside] = np.nan
        inv_y[~inside] = np.nan
        return inv_x, inv_y

    def save(self, path: str | Path) -> Path:
        """Write the map as ``.npz`` (temporary file renamed into place)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez_compressed(
            tmp,
            version=np.int32(1),
            camera_size=np.asarray(self.camera_size, np.int32),
            projector_size=np.asarray(self.projector_size, np.int32),
            roi=np.asarray(self.roi, np.int32),
            proj_x=self.proj_x.astype(np.float32),
            proj_y=self.proj_y.astype(np.float32),
            source=np.asarray(self.source),
            photometric=np.asarray(
                [np.nan if self.black_level is None else self.black_level, np.nan if self.gamma is None else self.gamma],
                np.float64,
            ),
            latency=np.asarray(
                [np.nan if v is None else v for v in (self.latency_s, self.latency_sigma_s)], np.float64
            ),
        )
        tmp.replace(path)
        return path


def _poly_terms(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """All monomials u^i v^j with i + j <= degree, as columns."""
    cols = [u**i * v**j for i in range(_INVERSE_DEGREE + 1) for j in range(_INVERSE_DEGREE + 1 - i)]
    return np.stack(cols, axis=1)


def _upsample_aligned(coarse: np.ndarray, width: int, height: int) -> np.ndarray:
    """Bilinear upsampling where coarse sample (j, i) sits on full pixel (j*step, i*step)."""
    xs = (np.arange(width, dtype=np.float32) / _INVERSE_STEP)[None, :].repeat(height, 0)
    ys = (np.arange(height, dtype=np.float32) / _INVERSE_STEP)[:, None].repeat(width, 1)
    return cv2.remap(coarse, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def sample(image: np.ndarray, xs: np.ndarray, ys: np.ndarray, border: float = np.nan) -> np.ndarray:
    """Bilinear samples of ``image`` at float points (any count; remap limits one axis to 32767)."""
    n = xs.size
    cols = 1024
    rows = -(-n // cols)
    px = np.zeros(rows * cols, np.float32)
    py = np.zeros(rows * cols, np.float32)
    px[:n], py[:n] = xs.ravel(), ys.ravel()
    out = cv2.remap(
        image.astype(np.float32, copy=False), px.reshape(rows, cols), py.reshape(rows, cols), cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT, borderValue=float(border),
    )
    return out.ravel()[:n].reshape(xs.shape)


def default_calibration(camera_size: Size, roi: Roi | None, projector_size: Size, margin: float = 0.08) -> ProjectorMap:
    """An uncalibrated stand-in: the ROI mapped affinely onto the projector frame (keeps the aspect, centred).

    Lets the daemon render and annotate before anyone ran `feelium calibrate projector`.
    """
    w, h = camera_size
    pw, ph = projector_size
    x, y, rw, rh = roi if roi is not None else (0, 0, w, h)
    scale = (1.0 - 2 * margin) * min(pw / rw, ph / rh)
    ox = (pw - rw * scale) / 2.0
    oy = (ph - rh * scale) / 2.0
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    proj_x = (ox + (xs - x) * scale).astype(np.float32)
    proj_y = (oy + (ys - y) * scale).astype(np.float32)
    outside = (xs < x) | (xs >= x + rw) | (ys < y) | (ys >= y + rh)
    proj_x[outside] = np.nan
    proj_y[outside] = np.nan
    return ProjectorMap((w, h), (pw, ph), (x, y, rw, rh), proj_x, proj_y, source="default")


def load_calibration(path: str | Path) -> ProjectorMap:
    """Read a map written by :meth:`ProjectorMap.save`; :class:`CalibrationError` names the file if it is wrong."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            version = int(data["version"])
            if version != 1:
                raise CalibrationError(f"{path}: unsupported calibration version {version}")
            cw, ch = (int(v) for v in data["camera_size"])
            pw, ph = (int(v) for v in data["projector_size"])
            roi = tuple(int(v) for v in data["roi"])
            proj_x = data["proj_x"].astype(np.float32, copy=False)  # saved as float32: no second copy
            proj_y = data["proj_y"].astype(np.float32, copy=False)
            source = str(data["source"])
            photo = data["photometric"] if "photometric" in data.files else np.array([np.nan, np.nan])
            black_level = float(photo[0]) if np.isfinite(photo[0]) else None
            gamma = float(photo[1]) if np.isfinite(photo[1]) else None
            timing = data["latency"] if "latency" in data.files else np.array([np.nan, np.nan])  # maps saved before it
            latency, sigma = (float(v) if np.isfinite(v) else None for v in timing)
    except CalibrationError:
        raise
    except (OSError, KeyError, ValueError) as exc:
        raise CalibrationError(f"{path}: not a projector calibration ({exc})") from exc
    try:
        return ProjectorMap(
            (cw, ch), (pw, ph), roi, proj_x, proj_y, source=source, black_level=black_level, gamma=gamma,  # type: ignore[arg-type]
            latency_s=latency, latency_sigma_s=sigma,
        )  # fmt: skip
    except CalibrationError as exc:
        raise CalibrationError(f"{path}: {exc}") from exc


_shared: weakref.WeakValueDictionary[tuple[str, int, int], ProjectorMap] = weakref.WeakValueDictionary()
_shared_lock = threading.Lock()


def load_shared(path: str | Path) -> ProjectorMap:
    """:func:`load_calibration`, but one map in memory for every caller while any of them holds it.

    The daemon's projector renders through the calibration, and the touch service annotates events and
    predicts the projected light through the same file: read separately, each part kept its own 2.4 MB copy
    (640x480 float32, x and y). The map's arrays are made read-only, so no part can change what the others see.
    A file rewritten since (``feelium calibrate projector``: new size or modification time) is read again.
    """
    path = Path(path)
    stat = path.stat() if path.exists() else None
    key = (str(path.resolve()), stat.st_mtime_ns if stat else -1, stat.st_size if stat else -1)
    with _shared_lock:  # services are built one after another, but keep two loads of one file from racing
        calibration = _shared.get(key)
        if calibration is None:
            calibration = load_calibration(path)
            calibration.proj_x.setflags(write=False)
            calibration.proj_y.setflags(write=False)
            _shared[key] = calibration
    return calibration


def calibration_path(file: str | Path, config_file: str | Path | None = None) -> Path:
    """The calibration file: absolute as configured (``[projector.calibration] file``), else beside ``config_file``.

    Relative to the config file rather than the working directory when one is
    given, so ``feelium calibrate projector --config X`` writes where the
    daemon started with ``--config X`` will look.
    """
    path = Path(file)
    if path.is_absolute():
        return path
    base = Path(config_file).resolve().parent if config_file else Path.cwd()
    return base / path


def load_or_default(path: Path, projector_size: Size, rear_roi: Roi | None) -> ProjectorMap:
    """The saved calibration, or the uncalibrated stand-in (ROI mapped affinely) when there is none.

    :class:`CalibrationError` when the file exists but cannot be read; a map made for
    another projector resolution is logged and replaced by the stand-in.
    """
    if path.exists():
        calibration = load_shared(path)
        if calibration.projector_size == tuple(projector_size):
            return calibration
        log.warning("%s is for a %s projector; using the uncalibrated map", path, calibration.projector_size)
    return default_calibration(DEFAULT_CAMERA_SIZE, rear_roi or DEFAULT_ROI, projector_size)
