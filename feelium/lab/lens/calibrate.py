"""Fit the front fisheye's OpenCV fisheye model from views of a chessboard or a ChArUco board (``feelium calibrate lens``).

A plain chessboard counts only when all of it is seen, and near a fisheye's rim (where the distortion is
measured) a whole board rarely fits; a ChArUco board's markers name each corner, so a view that shows part
of the board still counts (at least ``MIN_CHARUCO_CORNERS`` corners over two rows and two columns).

The headset places everything it draws over the video with this model, so the fit reports what it is worth:
the RMS reprojection error over all corners (recomputed here with ``cv2.fisheye.projectPoints`` rather than
trusted from the solver) and each view's own, so a blurred or mis-detected view shows up instead of
silently bending the lens.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np

from feelium.cameras.lens import FisheyeLens

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
MIN_VIEWS = 4
MIN_CHARUCO_CORNERS = 8


class LensCalibrationError(ValueError):
    """Too few usable views, or the solver failed; says what to do about it."""


@dataclass(frozen=True)
class Board:
    """A chessboard of ``cols x rows`` *inner* corners, squares ``square_m`` metres wide."""

    cols: int
    rows: int
    square_m: float

    @classmethod
    def parse(cls, pattern: str, square_mm: float) -> "Board":
        """From ``"9x6"`` (inner corners) and the printed square size in millimetres."""
        cols, _, rows = pattern.lower().partition("x")
        try:
            board = cls(int(cols), int(rows), square_mm / 1000.0)
        except ValueError:
            raise LensCalibrationError(f"pattern must be COLSxROWS inner corners, e.g. 9x6, got {pattern!r}") from None
        if board.cols < 3 or board.rows < 3 or not board.square_m > 0:
            raise LensCalibrationError("a board needs at least 3x3 inner corners and a positive square size")
        return board

    def object_points(self) -> np.ndarray:
        """Corner positions on the board (metres, z = 0), row by row as OpenCV detects them."""
        ys, xs = np.mgrid[0 : self.rows, 0 : self.cols]
        return np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1).astype(np.float64) * self.square_m

    def detect(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """(image points, board points) of the whole board, or ``None`` when any of it is not seen."""
        corners = find_corners(gray, self)
        return None if corners is None else (corners, self.object_points())

    def describe(self) -> str:
        return f"the whole {self.cols}x{self.rows} chessboard"


@dataclass(frozen=True)
class CharucoBoard:
    """A ChArUco board of ``cols x rows`` *squares* (OpenCV's layout: markers in the white squares), squares
    ``square_m`` and markers ``marker_m`` wide, markers from the predefined ArUco ``dictionary``."""

    cols: int
    rows: int
    square_m: float
    marker_m: float
    dictionary: str = "DICT_5X5_100"

    @classmethod
    def parse(cls, pattern: str, square_mm: float, marker_mm: float, dictionary: str = "DICT_5X5_100") -> "CharucoBoard":
        """From ``"11x8"`` (squares), the printed square and marker sizes in millimetres, and a dictionary name."""
        cols, _, rows = pattern.lower().partition("x")
        try:
            board = cls(int(cols), int(rows), square_mm / 1000.0, marker_mm / 1000.0, dictionary)
        except ValueError:
            raise LensCalibrationError(f"a ChArUco pattern is COLSxROWS squares, e.g. 11x8, got {pattern!r}") from None
        if board.cols < 3 or board.rows < 3 or not 0 < board.marker_m < board.square_m:
            raise LensCalibrationError("a ChArUco board needs at least 3x3 squares and markers smaller than the squares")
        if not isinstance(getattr(cv2.aruco, dictionary, None), int):
            raise LensCalibrationError(f"{dictionary!r} is not an OpenCV ArUco dictionary (e.g. DICT_5X5_100, DICT_4X4_50)")
        if (board.cols * board.rows) // 2 > int(dictionary.rsplit("_", 1)[-1]):
            raise LensCalibrationError(f"{dictionary} has fewer markers than a {pattern} board needs")
        return board

    @cached_property
    def opencv(self) -> "cv2.aruco.CharucoBoard":
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.cols, self.rows), self.square_m, self.marker_m, dictionary)

    def object_points(self) -> np.ndarray:
        """Every inner corner on the board (metres, z = 0), in OpenCV's ChArUco id order."""
        return np.asarray(self.opencv.getChessboardCorners(), dtype=np.float64).reshape(-1, 3)

    def detect(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """(image points, board points) of the corners the markers identify, or ``None`` when too few are seen to
        constrain a pose (fewer than ``MIN_CHARUCO_CORNERS``, or all on one row or one column)."""
        corners, ids, _, _ = cv2.aruco.CharucoDetector(self.opencv).detectBoard(gray)
        if ids is None or len(ids) < MIN_CHARUCO_CORNERS:
            return None
        ids = ids.ravel()
        inner_cols = self.cols - 1
        if len(set(ids % inner_cols)) < 2 or len(set(ids // inner_cols)) < 2:
            return None
        return corners.reshape(-1, 2).astype(np.float64), self.object_points()[ids]

    def describe(self) -> str:
        return f"at least {MIN_CHARUCO_CORNERS} corners of the {self.cols}x{self.rows} ChArUco board"


class Target(Protocol):
    """A calibration target: finds itself in a gray view, as matched image and board points."""

    def object_points(self) -> np.ndarray: ...

    def detect(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None: ...

    def describe(self) -> str: ...


@dataclass
class Calibration:
    """The fitted lens and how well it explains each view."""

    lens: FisheyeLens
    views_used: list[str]
    views_without_board: list[str]
    view_rms_px: list[float] = field(default_factory=list)

    def summary(self) -> dict[str, object]:
        return {
            "rms_px": self.lens.rms_px,
            "views_used": len(self.views_used),
            "views_without_board": len(self.views_without_board),
            "worst_view": max(zip(self.view_rms_px, self.views_used), default=(None, None))[1],
            "worst_view_rms_px": max(self.view_rms_px, default=None),
            "lens": self.lens.to_json(),
        }


def find_corners(gray: np.ndarray, board: Board) -> np.ndarray | None:
    """The board's inner corners ``(N, 2)`` to sub-pixel accuracy, or ``None`` when the whole board is not seen.

    ``findChessboardCornersSB`` (a localized radon transform) is more accurate than the classic
    detector plus ``cornerSubPix``, and copes with the curvature a fisheye adds to the board's lines.
    """
    found, corners = cv2.findChessboardCornersSB(gray, (board.cols, board.rows), flags=cv2.CALIB_CB_ACCURACY)
    return corners.reshape(-1, 2).astype(np.float64) if found else None


def _fisheye_flag(name: str) -> int:
    """A ``cv2.fisheye`` flag: in ``cv2.fisheye`` up to OpenCV 4 (the Pi's), merged into ``cv2`` with new values in 5."""
    return int(getattr(cv2.fisheye, name, None) or getattr(cv2, name))


def initial_k(size: tuple[int, int], fov_deg: float) -> np.ndarray:
    """A starting guess: an equidistant lens whose ``fov_deg`` image circle touches the frame's shorter sides."""
    width, height = size
    f = min(width, height) / 2.0 / np.radians(fov_deg / 2.0)
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])


# The solver only converges from a focal length near the truth (on the synthetic views: from 120-160 degree
# guesses for a lens of about 140, and to RMS 60-200 px from the others), so it starts from each of these
# fields of view and the fit with the smallest reprojection error wins (about 40 ms a start for 10 views).
START_FOVS_DEG = tuple(range(90, 271, 10))


def calibrate(views: Iterable[tuple[str, np.ndarray]], board: Target) -> Calibration:
    """Fit K and D (``cv2.fisheye.calibrate``, no skew) from named gray or BGR images of ``board``."""
    image_points: list[np.ndarray] = []
    object_points: list[np.ndarray] = []
    used: list[str] = []
    missing: list[str] = []
    size: tuple[int, int] | None = None
    for name, image in views:
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if size is None:
            size = (gray.shape[1], gray.shape[0])
        elif size != (gray.shape[1], gray.shape[0]):
            raise LensCalibrationError(f"{name} is {gray.shape[1]}x{gray.shape[0]}, the first view {size[0]}x{size[1]}: one camera mode per calibration")
        found = board.detect(gray)
        if found is None:
            missing.append(name)
        else:
            image_points.append(found[0])
            object_points.append(found[1])
            used.append(name)
    if size is None or len(used) < MIN_VIEWS:
        raise LensCalibrationError(
            f"{board.describe()} was found in {len(used)} view(s), at least {MIN_VIEWS} are needed: "
            "show it, tilted, in every part of the image (the edges matter most for a fisheye)"
        )
    fits = [fit for fov in START_FOVS_DEG if (fit := _fit(object_points, image_points, size, fov)) is not None]
    if not fits:
        raise LensCalibrationError("cv2.fisheye.calibrate failed from every start: add views with the board less steeply tilted")
    rms, k, d, residuals = min(fits, key=lambda fit: fit[0])
    lens = FisheyeLens(
        size[0], size[1], float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]),
        tuple(float(v) for v in np.ravel(d)), "calibrated", round(rms, 4),  # type: ignore[arg-type]
    )  # fmt: skip
    return Calibration(lens, used, missing, [round(float(np.sqrt(np.mean(r))), 4) for r in residuals])


def _fit(
    object_points: list[np.ndarray], image_points: list[np.ndarray], size: tuple[int, int], fov_deg: float
) -> tuple[float, np.ndarray, np.ndarray, list[np.ndarray]] | None:
    """One solver run from a ``fov_deg`` guess: (RMS, K, D, squared residuals per view), or ``None`` if it failed.

    The RMS is recomputed with ``cv2.fisheye.projectPoints`` over every corner of every view.
    """
    objects = [o.reshape(1, -1, 3).astype(np.float32) for o in object_points]  # the bindings want float32 (1, N, c)
    images = [p.reshape(1, -1, 2).astype(np.float32) for p in image_points]
    flags = _fisheye_flag("CALIB_RECOMPUTE_EXTRINSIC") | _fisheye_flag("CALIB_FIX_SKEW") | _fisheye_flag("CALIB_USE_INTRINSIC_GUESS")
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    try:
        _, k, d, rvecs, tvecs = cv2.fisheye.calibrate(objects, images, size, initial_k(size, fov_deg), np.zeros(4), flags=flags, criteria=criteria)
    except cv2.error:
        return None
    residuals = []
    for rvec, tvec, obj, seen in zip(rvecs, tvecs, object_points, image_points):
        projected, _ = cv2.fisheye.projectPoints(obj.reshape(-1, 1, 3), rvec, tvec, k, d)
        residuals.append(np.sum((projected.reshape(-1, 2) - seen) ** 2, axis=1))
    rms = float(np.sqrt(np.mean(np.concatenate(residuals))))
    return (rms, k, d, residuals) if np.isfinite(rms) else None


def read_views(source: str | Path, every: int = 1) -> Iterator[tuple[str, np.ndarray]]:
    """Images of a folder (sorted by name), or every ``every``-th frame of a video or a recording's ``camera.mkv``."""
    path = Path(source)
    if path.is_dir() and not (path / "camera.mkv").exists():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise LensCalibrationError(f"{path}: no images ({', '.join(IMAGE_SUFFIXES)})")
        for file in files[::every]:
            image = cv2.imread(str(file), cv2.IMREAD_COLOR)
            if image is None:
                raise LensCalibrationError(f"{file}: not an image OpenCV can read")
            yield file.name, image
        return
    video = path / "camera.mkv" if path.is_dir() else path
    capture = cv2.VideoCapture(str(video))
    if not capture.isOpened():
        raise LensCalibrationError(f"{video}: cannot open it as a video (give a folder of images, a video or a recording)")
    try:
        index = 0
        while True:
            ok, frame = capture.read()
            if not ok:
                return
            if index % every == 0:
                yield f"frame {index}", frame
            index += 1
    finally:
        capture.release()
