"""Reader and writer of the Feelium recording format, version 1.

The format (``docs/recording-format.md``) is the one contract between
the blimp, the simulator, replay, evaluation and the tests, so the reader is
strict: anything malformed is a :class:`RecordingError` that names the file
and what is wrong, before a single frame is handed downstream.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

FORMAT = "feelium.recording"
VERSION = 1
TOUCH_LABELS = ("tap", "hold", "swipe")
NEGATIVE_LABELS = ("hover", "disturbance", "empty")
CLIP_LABELS = ("contact", "hover", "empty")
PIXEL_FORMATS = ("gray8", "bgr8")


class RecordingError(ValueError):
    """A recording is malformed; the message names the file and the problem."""

    def __init__(self, path: Path | str, message: str) -> None:
        super().__init__(f"{path}: {message}")
        self.path = Path(path)


@dataclass(frozen=True)
class Contact:
    """One interval during which something touched the membrane, with its true path."""

    t_on: float
    t_off: float
    path: np.ndarray | None  # (K, 3) rows of [t, x, y] in camera pixels, or None

    def position_at(self, t: float) -> tuple[float, float] | None:
        """The labelled fingertip position at time ``t`` (linear interpolation), if a path exists."""
        if self.path is None or len(self.path) == 0:
            return None
        ts, xs, ys = self.path[:, 0], self.path[:, 1], self.path[:, 2]
        return float(np.interp(t, ts, xs)), float(np.interp(t, ts, ys))


@dataclass(frozen=True)
class Labels:
    """Ground truth of a recording."""

    label: str
    clip: bool
    target: tuple[float, float] | None
    contacts: tuple[Contact, ...]

    def to_json(self) -> dict[str, Any]:
        obj: dict[str, Any] = {
            "label": self.label,
            "target": list(self.target) if self.target is not None else None,
            "contacts": [
                {
                    "t_on": c.t_on,
                    "t_off": c.t_off,
                    **({"path": np.asarray(c.path).round(3).tolist()} if c.path is not None else {}),
                }
                for c in self.contacts
            ],
        }
        if self.clip:
            obj["clip"] = True
        return obj


@dataclass(frozen=True)
class CameraInfo:
    width: int
    height: int
    fps: float
    pixel_format: str


@dataclass(frozen=True)
class Meta:
    """``meta.json``: what the recording is. ``raw`` keeps unknown keys for round trips."""

    name: str
    session: str
    source: str
    camera: CameraInfo
    roi: tuple[int, int, int, int] | None
    thermal: dict[str, Any] | None
    raw: dict[str, Any]


@dataclass(frozen=True)
class ThermalData:
    t: np.ndarray  # (N,) float64
    celsius: np.ndarray  # (N, 24, 32) float32
    eeprom: np.ndarray | None = None  # (832,) uint16
    ram: np.ndarray | None = None  # (N, 834) uint16


def _fail(path: Path, message: str) -> RecordingError:
    return RecordingError(path, message)


def _read_json(path: Path) -> Any:
    if not path.is_file():
        raise _fail(path, "missing file")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise _fail(path, f"not valid JSON: {exc}") from exc


def _parse_meta(path: Path) -> Meta:
    obj = _read_json(path)
    if not isinstance(obj, dict):
        raise _fail(path, "expected a JSON object")
    if obj.get("format") != FORMAT:
        raise _fail(path, f"format must be {FORMAT!r}, got {obj.get('format')!r}")
    if obj.get("version") != VERSION:
        raise _fail(path, f"unknown version {obj.get('version')!r}; this reader knows version {VERSION}")
    cam = obj.get("camera")
    if not isinstance(cam, dict):
        raise _fail(path, "camera: expected an object with width, height, fps, pixel_format")
    try:
        camera = CameraInfo(int(cam["width"]), int(cam["height"]), float(cam["fps"]), str(cam["pixel_format"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise _fail(path, f"camera: missing or bad field {exc}") from exc
    if camera.pixel_format not in PIXEL_FORMATS:
        raise _fail(path, f"camera.pixel_format must be one of {PIXEL_FORMATS}, got {camera.pixel_format!r}")
    if camera.width <= 0 or camera.height <= 0:
        raise _fail(path, "camera width and height must be positive")
    roi_raw = obj.get("roi")
    roi: tuple[int, int, int, int] | None = None
    if roi_raw is not None:
        if not (isinstance(roi_raw, list) and len(roi_raw) == 4):
            raise _fail(path, "roi: expected [x, y, w, h] or null")
        x, y, w, h = (int(v) for v in roi_raw)
        if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > camera.width or y + h > camera.height:
            raise _fail(path, f"roi {roi_raw} does not fit the {camera.width}x{camera.height} frame")
        roi = (x, y, w, h)
    return Meta(
        name=str(obj.get("name", path.parent.name)),
        session=str(obj.get("session", "")),
        source=str(obj.get("source", "device")),
        camera=camera,
        roi=roi,
        thermal=obj.get("thermal"),
        raw=obj,
    )


def read_timestamps(path: Path) -> np.ndarray:
    """Frame times from a ``*_ts.txt`` file; rejects non-numbers and backwards steps."""
    if not path.is_file():
        raise _fail(path, "missing file")
    values = []
    for lineno, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        text = line.strip()
        if not text:
            continue
        try:
            value = float(text)
        except ValueError as exc:
            raise _fail(path, f"line {lineno}: not a number: {text!r}") from exc
        if not math.isfinite(value):
            raise _fail(path, f"line {lineno}: not a finite time: {text!r}")
        values.append(value)
    ts = np.asarray(values, dtype=np.float64)
    if len(ts) > 1:
        back = np.flatnonzero(np.diff(ts) < 0)
        if len(back):
            i = int(back[0]) + 1
            raise _fail(path, f"line {i + 1}: time goes backwards ({ts[i - 1]} then {ts[i]})")
    return ts


def _parse_labels(path: Path) -> Labels:
    obj = _read_json(path)
    if not isinstance(obj, dict) or "label" not in obj:
        raise _fail(path, "expected an object with a 'label'")
    clip = bool(obj.get("clip", False))
    label = obj["label"]
    allowed = CLIP_LABELS if clip else TOUCH_LABELS + NEGATIVE_LABELS
    if label not in allowed:
        raise _fail(path, f"label {label!r} is not one of {allowed}")
    target = obj.get("target")
    if target is not None:
        if not (isinstance(target, list) and len(target) == 2):
            raise _fail(path, "target: expected [x, y] or null")
        target = (float(target[0]), float(target[1]))
    contacts = []
    for i, c in enumerate(obj.get("contacts", [])):
        try:
            t_on, t_off = float(c["t_on"]), float(c["t_off"])
        except (KeyError, TypeError, ValueError) as exc:
            raise _fail(path, f"contacts[{i}]: needs numeric t_on and t_off") from exc
        if t_off < t_on:
            raise _fail(path, f"contacts[{i}]: t_off {t_off} is before t_on {t_on}")
        contact_path = None
        if c.get("path") is not None:
            arr = np.asarray(c["path"], dtype=np.float64)
            if arr.ndim != 2 or arr.shape[1] != 3:
                raise _fail(path, f"contacts[{i}].path: expected rows of [t, x, y]")
            contact_path = arr
        contacts.append(Contact(t_on, t_off, contact_path))
    return Labels(label=label, clip=clip, target=target, contacts=tuple(contacts))


class Recording:
    """One recording directory, validated on open; frames are decoded lazily."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_dir():
            raise RecordingError(self.path, "not a directory")
        self.meta = _parse_meta(self.path / "meta.json")
        self.timestamps = read_timestamps(self.path / "camera_ts.txt")
        video = self.path / "camera.mkv"
        if not video.is_file():
            raise _fail(video, "missing file")
        count = _frame_count(video)
        if count != len(self.timestamps):
            raise _fail(
                self.path / "camera_ts.txt",
                f"{len(self.timestamps)} timestamps but camera.mkv has {count} frames",
            )
        labels_path = self.path / "labels.json"
        self.labels: Labels | None = _parse_labels(labels_path) if labels_path.exists() else None

    @property
    def name(self) -> str:
        return self.meta.name

    def __len__(self) -> int:
        return len(self.timestamps)

    def frames(self, *, gray: bool = True) -> Iterator[tuple[float, np.ndarray]]:
        """Yield ``(t, frame)`` in order; gray frames are (H, W) uint8, else (H, W, 3) BGR."""
        video = self.path / "camera.mkv"
        cap = cv2.VideoCapture(str(video))
        if not cap.isOpened():
            raise _fail(video, "cannot be decoded")
        cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
        try:
            for t in self.timestamps:
                ok, frame = cap.read()
                if not ok:
                    raise _fail(video, "ended before its timestamps did")
                yield float(t), _as_pixel_format(frame, gray)
        finally:
            cap.release()

    def thermal(self) -> ThermalData | None:
        path = self.path / "thermal.npz"
        if not path.exists():
            return None
        try:
            with np.load(path) as data:
                t = np.asarray(data["t"], dtype=np.float64)
                celsius = np.asarray(data["celsius"], dtype=np.float32)
                eeprom = np.asarray(data["eeprom"], dtype=np.uint16) if "eeprom" in data else None
                ram = np.asarray(data["ram"], dtype=np.uint16) if "ram" in data else None
        except (OSError, KeyError, ValueError) as exc:
            raise _fail(path, f"cannot read thermal data: {exc}") from exc
        if celsius.ndim != 3 or celsius.shape[1:] != (24, 32) or len(t) != len(celsius):
            raise _fail(path, f"celsius must be (N, 24, 32) matching t; got {celsius.shape} and {t.shape}")
        if ram is not None and (ram.ndim != 2 or ram.shape != (len(t), 834)):
            raise _fail(path, f"ram must be (N, 834); got {ram.shape}")
        if eeprom is not None and eeprom.shape != (832,):
            raise _fail(path, f"eeprom must be (832,); got {eeprom.shape}")
        return ThermalData(t=t, celsius=celsius, eeprom=eeprom, ram=ram)


def _frame_count(video: Path) -> int:
    """Exact frame count by decoding (container metadata is not trusted for FFV1 in MKV)."""
    cap = cv2.VideoCapture(str(video))
    if not cap.isOpened():
        raise _fail(video, "cannot be decoded")
    cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
    count = 0
    try:
        while cap.grab():
            count += 1
    finally:
        cap.release()
    return count


def _as_pixel_format(frame: np.ndarray, gray: bool) -> np.ndarray:
    if frame.ndim == 3 and frame.shape[2] == 4:
        frame = frame[:, :, :3]  # FFV1 stores BGR as bgr0; the padding byte carries nothing
    if gray:
        if frame.ndim == 2:
            return frame
        if frame.shape[2] == 1:
            return frame[:, :, 0]
        return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    return frame


def find_recordings(root: str | Path) -> list[Path]:
    """Every recording (directory with a ``meta.json``) under ``root``, sorted, root included."""
    root = Path(root)
    if not root.exists():
        raise RecordingError(root, "no such file or directory")
    found = sorted(p.parent for p in root.rglob("meta.json"))
    if not found:
        raise RecordingError(root, "holds no recording (no meta.json below it)")
    return found


class RecordingWriter:
    """Writes one recording atomically: into a temp dir beside the target, renamed on close.

    Use as a context manager; an exception inside the block discards the
    partial recording, so a crash never leaves something that looks whole.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        name: str,
        width: int,
        height: int,
        fps: float,
        pixel_format: str = "gray8",
        session: str = "",
        source: str = "synthetic",
        roi: tuple[int, int, int, int] | None = None,
        extra_meta: dict[str, Any] | None = None,
        overwrite: bool = False,
    ) -> None:
        if pixel_format not in PIXEL_FORMATS:
            raise ValueError(f"pixel_format must be one of {PIXEL_FORMATS}")
        self.path = Path(path)
        if self.path.exists() and not overwrite:
            raise FileExistsError(f"{self.path}: already exists")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", dir=self.path.parent))
        self._overwrite = overwrite
        self._meta: dict[str, Any] = {
            "format": FORMAT,
            "version": VERSION,
            "name": name,
            "session": session,
            "source": source,
            "camera": {"width": width, "height": height, "fps": fps, "pixel_format": pixel_format},
            "roi": list(roi) if roi is not None else None,
            "thermal": None,
        }
        if extra_meta:
            self._meta.update(extra_meta)
        self._gray = pixel_format == "gray8"
        self._size = (width, height)
        self._video = cv2.VideoWriter(
            str(self._tmp / "camera.mkv"), cv2.VideoWriter_fourcc(*"FFV1"), fps, (width, height), isColor=not self._gray
        )
        if not self._video.isOpened():
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise RuntimeError("OpenCV cannot write FFV1/Matroska here (needs its FFmpeg backend)")
        self._ts = (self._tmp / "camera_ts.txt").open("w", encoding="utf-8")
        self._last_t = -math.inf
        self._labels: Labels | None = None
        self._thermal: ThermalData | None = None
        self.frames_written = 0

    def add_frame(self, t: float, frame: np.ndarray) -> None:
        """Append one frame with its capture time (seconds; must not go backwards)."""
        if not math.isfinite(t) or t < self._last_t:
            raise ValueError(f"frame time {t} is not finite or goes backwards (last {self._last_t})")
        expected = (self._size[1], self._size[0])
        if frame.shape[:2] != expected:
            raise ValueError(f"frame is {frame.shape[:2]}, recording is {expected}")
        if frame.dtype != np.uint8:
            raise ValueError("frames must be uint8")
        if self._gray and frame.ndim == 3:
            frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        if not self._gray and frame.ndim == 2:
            frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        self._video.write(np.ascontiguousarray(frame))
        self._ts.write(f"{t:.6f}\n")
        self._last_t = t
        self.frames_written += 1

    def set_labels(self, labels: Labels) -> None:
        self._labels = labels

    def set_thermal(self, thermal: ThermalData, fps: float) -> None:
        self._thermal = thermal
        self._meta["thermal"] = {"width": 32, "height": 24, "fps": fps}

    def close(self) -> Path:
        """Finish the files and move the recording into place."""
        self._video.release()
        self._ts.close()
        (self._tmp / "meta.json").write_text(json.dumps(self._meta, indent=1) + "\n", encoding="utf-8")
        if self._labels is not None:
            (self._tmp / "labels.json").write_text(json.dumps(self._labels.to_json()) + "\n", encoding="utf-8")
        if self._thermal is not None:
            arrays: dict[str, np.ndarray] = {"t": self._thermal.t, "celsius": self._thermal.celsius}
            if self._thermal.eeprom is not None:
                arrays["eeprom"] = self._thermal.eeprom
            if self._thermal.ram is not None:
                arrays["ram"] = self._thermal.ram
            np.savez_compressed(self._tmp / "thermal.npz", **arrays)
        if self.path.exists() and self._overwrite:
            shutil.rmtree(self.path)
        os.replace(self._tmp, self.path)
        return self.path

    def abort(self) -> None:
        self._video.release()
        self._ts.close()
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
