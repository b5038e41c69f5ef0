"""Reader and writer of the Feelium recording format, version 1.

The format (``docs/recording-format.md``) is the one contract between
the blimp, the simulator, replay, evaluation and the tests, so the reader is
strict: anything malformed is a :class:`RecordingError` that names the file
and what is wrong, before a single frame is handed downstream.
"""

from __future__ import annotations

import errno
import functools
import io
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
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
CONTACT_KINDS = ("finger", "palm", "hug")  # what touched: the events' ``contact`` key (docs/touch.md)


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
    # Optional (docs/recording-format.md, proposed): what touched, ``finger``, ``palm`` or ``hug``. A trial whose
    # contacts carry it is scored contact by contact too: each entry one touch with an id of its own.
    contact: str | None = None

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
    # Optional (docs/recording-format.md, proposed): when the room's light was switched (on or off), seconds on the
    # camera clock. Why a label: a switch is what recovery after a switch is measured from (``eval``), and only the
    # person (or simulator) making the take knows it; the frames alone do not say what was switched.
    light_switches: tuple[float, ...] = ()

    def to_json(self) -> dict[str, Any]:
        obj: dict[str, Any] = {
            "label": self.label,
            "target": list(self.target) if self.target is not None else None,
            "contacts": [
                {
                    "t_on": c.t_on,
                    "t_off": c.t_off,
                    **({"path": np.asarray(c.path).round(3).tolist()} if c.path is not None else {}),
                    **({"contact": c.contact} if c.contact is not None else {}),
                }
                for c in self.contacts
            ],
        }
        if self.clip:
            obj["clip"] = True
        if self.light_switches:
            obj["light_switches"] = [round(float(t), 4) for t in self.light_switches]
        return obj


@dataclass(frozen=True)
class CameraInfo:
    width: int
    height: int
    fps: float
    pixel_format: str
    # Optional ``camera.exposure_s``: the shutter time the frames were taken with, when the recorder knew it (what a
    # calibration recording's latency is measured against, :mod:`feelium.lab.projector.latency`); None: not said.
    exposure_s: float | None = None


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
        exposure = cam.get("exposure_s")
        camera = CameraInfo(
            int(cam["width"]), int(cam["height"]), float(cam["fps"]), str(cam["pixel_format"]),
            None if exposure is None else float(exposure),
        )  # fmt: skip
    except (KeyError, TypeError, ValueError) as exc:
        raise _fail(path, f"camera: missing or bad field {exc}") from exc
    if camera.pixel_format not in PIXEL_FORMATS:
        raise _fail(path, f"camera.pixel_format must be one of {PIXEL_FORMATS}, got {camera.pixel_format!r}")
    if camera.width <= 0 or camera.height <= 0:
        raise _fail(path, "camera width and height must be positive")
    if not (math.isfinite(camera.fps) and camera.fps > 0):
        raise _fail(path, f"camera.fps must be a positive number, got {cam['fps']!r}")
    if camera.exposure_s is not None and not (math.isfinite(camera.exposure_s) and camera.exposure_s >= 0):
        raise _fail(path, f"camera.exposure_s must be a number >= 0, got {cam['exposure_s']!r}")
    return Meta(
        name=str(obj.get("name", path.parent.name)),
        session=str(obj.get("session", "")),
        source=str(obj.get("source", "device")),
        camera=camera,
        roi=_parse_roi(path, obj.get("roi"), camera),
        thermal=obj.get("thermal"),
        raw=obj,
    )


def _parse_roi(path: Path, raw: Any, camera: CameraInfo) -> tuple[int, int, int, int] | None:
    """``[x, y, w, h]`` of whole pixels inside the frame, or ``None`` for the whole frame."""
    if raw is None:
        return None
    if not (isinstance(raw, list) and len(raw) == 4 and all(_is_whole(v) for v in raw)):
        raise _fail(path, f"roi: expected [x, y, w, h] of whole pixels or null, got {raw!r}")
    x, y, w, h = (int(v) for v in raw)
    if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > camera.width or y + h > camera.height:
        raise _fail(path, f"roi {raw} does not fit the {camera.width}x{camera.height} frame")
    return x, y, w, h


def _is_whole(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value == int(value)


def _number(value: Any) -> float | None:
    """``value`` as a finite float, or ``None`` when it is not a finite number (JSON true is not one)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)


def read_timestamps(path: Path) -> np.ndarray:
    """Frame times from a ``*_ts.txt`` file; rejects non-numbers and times that do not advance.

    The spec says times never go backwards; a repeated time is rejected as well, because one camera
    cannot capture two frames at the same instant and downstream rates and latencies divide by the step.
    """
    if not path.is_file():
        raise _fail(path, "missing file")
    try:
        text_of_file = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise _fail(path, f"not UTF-8 text (byte {exc.start})") from exc
    except OSError as exc:
        raise _fail(path, f"cannot be read: {exc.strerror or exc}") from exc
    values = []
    for lineno, line in enumerate(text_of_file.splitlines(), start=1):
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
        stuck = np.flatnonzero(np.diff(ts) <= 0)
        if len(stuck):
            i = int(stuck[0]) + 1
            how = "goes backwards" if ts[i] < ts[i - 1] else "repeats"
            raise _fail(path, f"line {i + 1}: time {how} ({ts[i - 1]} then {ts[i]})")
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
    raw_target = obj.get("target")
    target = None
    if raw_target is not None:
        xy = [_number(v) for v in raw_target] if isinstance(raw_target, list) else []
        if len(xy) != 2 or None in xy:
            raise _fail(path, f"target: expected [x, y] numbers or null, got {raw_target!r}")
        target = (float(xy[0]), float(xy[1]))  # type: ignore[arg-type]
    raw_contacts = obj.get("contacts", [])
    if not isinstance(raw_contacts, list):
        raise _fail(path, "contacts: expected a list")
    contacts = []
    for i, c in enumerate(raw_contacts):
        t_on = _number(c.get("t_on")) if isinstance(c, dict) else None
        t_off = _number(c.get("t_off")) if isinstance(c, dict) else None
        if t_on is None or t_off is None:
            raise _fail(path, f"contacts[{i}]: needs numeric t_on and t_off")
        if t_off < t_on:
            raise _fail(path, f"contacts[{i}]: t_off {t_off} is before t_on {t_on}")
        kind = c.get("contact")
        if kind is not None and kind not in CONTACT_KINDS:
            raise _fail(path, f"contacts[{i}].contact: {kind!r} is not one of {CONTACT_KINDS}")
        contacts.append(Contact(t_on, t_off, _parse_path(path, i, c.get("path")), kind))
    raw_switches = obj.get("light_switches", [])
    switches = [_number(v) for v in raw_switches] if isinstance(raw_switches, list) else [None]
    if None in switches:
        raise _fail(path, f"light_switches: expected a list of times in seconds, got {raw_switches!r}")
    return Labels(
        label=label, clip=clip, target=target, contacts=tuple(contacts),
        light_switches=tuple(sorted(float(t) for t in switches)),  # type: ignore[arg-type]
    )  # fmt: skip


def check_labels_fit(recording: "Recording") -> None:
    """Refuse labels that contradict themselves or their take, naming the field (:class:`RecordingError`).

    For whatever scores against the labels (``eval``, ``calibrate touch``): they would be scored as if true.
    Replaying frames does not need them, so opening a recording does not check this. A touch trial (or a
    ``contact`` clip) needs a contact and a negative has none (the spec: "empty for negatives"); the target
    lies in the camera frame; every contact overlaps the take's frames. Contacts may overlap each other (two
    hands at once)."""
    labels, timestamps = recording.labels, recording.timestamps
    if labels is None:
        return
    path = recording.path / "labels.json"
    width, height = recording.meta.camera.width, recording.meta.camera.height
    touch = labels.label == "contact" if labels.clip else labels.label in TOUCH_LABELS
    if touch and not labels.contacts:
        raise _fail(path, f"label {labels.label!r} needs at least one entry in contacts")
    if not touch and labels.contacts:
        raise _fail(path, f"label {labels.label!r} is a negative: its contacts must be empty, got {len(labels.contacts)}")
    if labels.target is not None and not (0.0 <= labels.target[0] <= width and 0.0 <= labels.target[1] <= height):
        raise _fail(path, f"target {list(labels.target)} lies outside the {width}x{height} camera frame")
    if len(timestamps) == 0:
        return
    first, last = float(timestamps[0]), float(timestamps[-1])
    for i, contact in enumerate(labels.contacts):
        if contact.t_off < first or contact.t_on > last:
            raise _fail(path, f"contacts[{i}]: {contact.t_on}-{contact.t_off} s lies outside the take's frames ({first:.3f}-{last:.3f} s)")


def _parse_path(path: Path, i: int, raw: Any) -> np.ndarray | None:
    """A contact's ``[t, x, y]`` rows as an (K, 3) float array, or ``None`` when absent."""
    if raw is None:
        return None
    rows = raw if isinstance(raw, list) else [None]
    if not all(isinstance(r, list) and len(r) == 3 and None not in map(_number, r) for r in rows):
        raise _fail(path, f"contacts[{i}].path: expected rows of three numbers [t, x, y]")
    return np.asarray(rows, dtype=np.float64).reshape(-1, 3)


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
        count, size = _probe_video(video, decode=False)
        if count != len(self.timestamps):
            count, size = _probe_video(video)  # a mismatch is confirmed (and its count named) by decoding
        if count != len(self.timestamps):
            raise _fail(
                self.path / "camera_ts.txt",
                f"{len(self.timestamps)} timestamps but camera.mkv has {count} frames",
            )
        declared = (self.meta.camera.width, self.meta.camera.height)
        if size is not None and size != declared:
            raise _fail(
                self.path / "meta.json",
                f"camera is {declared[0]}x{declared[1]} but camera.mkv holds {size[0]}x{size[1]} frames",
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
        return _decode(self.path / "camera.mkv", self.timestamps, gray)

    @property
    def has_projector(self) -> bool:
        """Whether the recording carries what the inner projector showed (``projector.mkv``)."""
        return (self.path / "projector.mkv").is_file()

    def projector_frames(self, *, gray: bool = True) -> Iterator[tuple[float, np.ndarray]]:
        """Yield the projector stream's ``(t, frame)`` in order (display times on the camera's clock).

        Checked as it is decoded (a projector stream is long and large: it is not decoded twice on open): a
        video that ends before ``projector_ts.txt`` does, or holds frames of another size than ``meta.projector``
        says, is a :class:`RecordingError`.
        """
        video = self.path / "projector.mkv"
        if not video.is_file():
            raise _fail(video, "missing file")
        info = self.meta.raw.get("projector")
        if not isinstance(info, dict) or not all(_is_whole(info.get(k)) for k in ("width", "height")):
            raise _fail(self.path / "meta.json", "projector: expected an object with width and height")
        size = (int(info["width"]), int(info["height"]))
        for t, frame in _decode(video, read_timestamps(self.path / "projector_ts.txt"), gray):
            if (frame.shape[1], frame.shape[0]) != size:
                raise _fail(video, f"holds {frame.shape[1]}x{frame.shape[0]} frames, meta.projector says {size[0]}x{size[1]}")
            yield t, frame

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


def _decode(video: Path, timestamps: np.ndarray, gray: bool) -> Iterator[tuple[float, np.ndarray]]:
    """``(t, frame)`` of ``video`` against its timestamps, one frame per line."""
    cap = cv2.VideoCapture(str(video))
    if not cap.isOpened():
        raise _fail(video, "cannot be decoded")
    cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
    try:
        for t in timestamps:
            ok, frame = cap.read()
            if not ok:
                raise _fail(video, "ended before its timestamps did")
            yield float(t), _as_pixel_format(frame, gray)
    finally:
        cap.release()


def _probe_video(video: Path, *, decode: bool = True) -> tuple[int, tuple[int, int] | None]:
    """Exact frame count and the first frame's (width, height).

    Container metadata is not trusted for FFV1 in MKV, so frames are counted one by one; the first is
    decoded in full to learn the size the pixels really have. With ``decode`` the others are decoded too
    (what a reader will get); without it they are counted as the container's packets, read but not
    decoded (FFV1 is intra-only: one packet per frame), about 100x cheaper on the simulator's 640x480 clips.
    A packet that does not decode is then counted but fails later, when :func:`_decode` reaches it.
    """
    cap = cv2.VideoCapture(str(video))
    if not cap.isOpened():
        raise _fail(video, "cannot be decoded")
    cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
    try:
        ok, first = cap.read()
        if not ok:
            return 0, None
        size = (int(first.shape[1]), int(first.shape[0]))
        if decode:
            return 1 + _count_grabs(cap), size
    finally:
        cap.release()
    raw = cv2.VideoCapture(str(video), cv2.CAP_FFMPEG)
    try:
        if not raw.set(cv2.CAP_PROP_FORMAT, -1):  # raw (undecoded) packets: refused by a backend without them
            return _probe_video(video)
        return _count_grabs(raw), size
    finally:
        raw.release()


def _count_grabs(cap: cv2.VideoCapture) -> int:
    """How many more frames ``cap`` grabs before its stream ends."""
    count = 0
    while cap.grab():
        count += 1
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


# -- the projector calibration of a recording with a projector stream (docs/recording-format.md) ---------------------

CALIBRATION_PURPOSE = "projector-calibration"  # meta.purpose of a calibration recording (structured light, no hand)
CALIBRATION_FILE = "projector-calibration.npz"  # a map saved by ProjectorMap.save, found beside the trials
# The name `feelium calibrate projector` saves on the blimp (`[projector.calibration] file`): a map copied from
# the blimp beside the trials is found under it too.
CALIBRATION_FILES = (CALIBRATION_FILE, "projector_calibration.npz")


def find_calibration(recording: Path, root: Path, session: str | None = None) -> Path | None:
    """The calibration beside the trials, in the recording's folder or the nearest folder above it up to the
    dataset ``root``: a saved map (:data:`CALIBRATION_FILE`), else a calibration recording (``meta.purpose``
    ``"projector-calibration"``) to fit the map from: the first by name of the trial's own ``session`` when
    that folder holds one, else the first by name. Why the session: the recording format fits the map of "the
    recordings beside it (same ``session``)", so a dataset may lay one calibration recording per session (per
    blimp, per day) side by side, and each trial must get its own projector's map."""
    here, top = recording.resolve(), root.resolve()
    for folder in (here, *here.parents):
        for name in CALIBRATION_FILES:
            candidate = folder / name
            if candidate.is_file():
                return candidate
        recordings = _calibration_recordings(folder)
        if recordings:
            same = [path for path, their_session in recordings if session is not None and their_session == session]
            return (same or [recordings[0][0]])[0]
        if folder == top or top not in folder.parents:
            break
    return None


@functools.lru_cache(maxsize=256)
def _calibration_recordings(folder: Path) -> tuple[tuple[Path, str | None], ...]:
    """The calibration recordings directly in ``folder``, by name, each with its ``meta.session`` (cached:
    every trial of a dataset asks its folder)."""
    found = []
    for child in sorted(folder.iterdir()) if folder.is_dir() else ():
        try:
            meta = json.loads((child / "meta.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(meta, dict) and meta.get("purpose") == CALIBRATION_PURPOSE:
            session = meta.get("session")
            found.append((child, session if isinstance(session, str) else None))
    return tuple(found)


RESERVE_BYTES = 32 * 1024 * 1024
"""Free space a take stops at, so the small files that close it still fit (see :class:`DiskFull`)."""

SET_ASIDE_BYTES = 8 * 1024 * 1024
"""Room a take claims at its start (a preallocated file in its temp dir) and gives back when it closes.

:data:`RESERVE_BYTES` only helps while this take is what fills the disk; another process can take the last
byte between two frames. Closing then still needs room: FFmpeg's Matroska muxer holds the current cluster in
memory (up to 5 MiB or 5 s) and writes it and the index on release, then come the timestamps and meta.json.
8 MiB covers that for a camera take of hours (11 bytes of timestamp a frame)."""
SET_ASIDE_NAME = ".set-aside"
JOURNAL_META, JOURNAL_TIMES = ".journal.json", ".journal_ts.txt"
JOURNAL_SYNC_S = 1.0
"""How often the journal of frame times is fsynced: a power cut loses at most this much of a take's end."""


class DiskFull(OSError):
    """The disk is nearly full: the take stops here and can still be closed as a valid, shorter recording."""

    def __init__(self, path: Path, free: int) -> None:
        super().__init__(errno.ENOSPC, f"disk nearly full ({free / 1e6:.1f} MB free)", str(path))


def _umask() -> int:
    """The process's umask: from /proc where Linux shows it, else by setting it and straight back (which
    another thread could see for an instant, so only where there is no other way)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def free_bytes(path: Path) -> int:
    """Bytes an unprivileged writer may still use on the file system holding ``path``."""
    return shutil.disk_usage(path).free


def set_aside(path: Path, size: int) -> None:
    """Claim ``size`` bytes of the disk as the new file ``path`` (blocks allocated, not just a sparse size),
    so that deleting it later is sure to give that much room back; :class:`OSError` (ENOSPC) if there is not."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        if size > 0:
            os.posix_fallocate(fd, 0, size)  # glibc writes the blocks itself where the file system cannot
    finally:
        os.close(fd)


def frames_held(video: Path, written: int) -> int:
    """How many of the ``written`` frames ``video`` really holds.

    FFmpeg writes where Python cannot see a failed write, and once one write fails it drops every later one,
    the index included. A video closed whole declares its length (Matroska's duration: ``written`` frames at
    the writer's fixed rate), which is checked first and costs one open; one that does not is counted by
    decoding, up to where the file ends."""
    cap = cv2.VideoCapture(str(video))
    declared = cap.get(cv2.CAP_PROP_FRAME_COUNT) if cap.isOpened() else -1.0
    cap.release()
    if round(declared) == written:
        return written
    try:
        return min(written, _probe_video(video)[0])
    except RecordingError:  # not even a header reached the disk
        return 0


def write_durably(path: Path, data: bytes) -> None:
    """Write ``data`` to a new file and fsync it, so a power cut after the rename cannot leave it empty."""
    with path.open("wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())


def fsync_path(path: Path) -> None:
    """fsync an existing file or directory (a directory's fsync makes the names in it durable)."""
    fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if path.is_dir() else 0))
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


OWN_FILES = frozenset(
    ("meta.json", "camera.mkv", "camera_ts.txt", "labels.json", "thermal.npz", "projector.mkv", "projector_ts.txt")
)  # the format's own files: what ``add_file`` must not overwrite


class RecordingWriter:
    """Writes one recording atomically: into a temp dir beside the target, fsynced, renamed on close.

    Use as a context manager; an exception inside the block discards the
    partial recording, so a crash never leaves something that looks whole.
    The video goes to disk as frames come (FFmpeg writes it, where Python
    cannot see a failed write), so ``add_frame`` refuses a frame with
    :class:`DiskFull` once less than ``reserve_bytes`` are free, or once the
    video writer says a frame was not written (OpenCV >= 5 does). A disk
    filled by another process between two frames is why ``set_aside_bytes``
    are claimed at the start and given back first thing in ``close``, and
    why ``close`` cuts the frame times (kept in memory until then) to the
    frames the video really holds. ``free`` is how free space is measured
    (a test gives a tiny disk).
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
        exposure_s: float | None = None,
        overwrite: bool = False,
        reserve_bytes: int = RESERVE_BYTES,
        set_aside_bytes: int = SET_ASIDE_BYTES,
        free: Callable[[Path], int] | None = None,
    ) -> None:
        if pixel_format not in PIXEL_FORMATS:
            raise ValueError(f"pixel_format must be one of {PIXEL_FORMATS}")
        self.path = Path(path)
        if self.path.exists() and not overwrite:
            raise FileExistsError(f"{self.path}: already exists")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", dir=self.path.parent))
        # mkdtemp makes it 0700 and the rename keeps that; a finished take is shared like any new directory
        os.chmod(self._tmp, 0o777 & ~_umask())
        self._set_aside = self._tmp / SET_ASIDE_NAME
        try:
            set_aside(self._set_aside, set_aside_bytes)
        except OSError:
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise
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
        if exposure_s is not None:  # the camera's shutter time, when the recorder knows it (optional key)
            self._meta["camera"]["exposure_s"] = float(exposure_s)
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
        self._times: list[float] = []
        # The take's journal (hidden, in the temp dir): who writes it, its meta and each frame's time as it comes,
        # so a take whose process was killed (SIGKILL, a power cut, the OOM killer) can be recovered later
        # (:func:`recover_interrupted`). Removed on close, when the real files are written.
        try:
            write_durably(self._tmp / JOURNAL_META, (json.dumps({"pid": os.getpid(), "target": self.path.name, "meta": self._meta}) + "\n").encode())
            self._journal = (self._tmp / JOURNAL_TIMES).open("w", encoding="ascii")
        except OSError:
            self._video.release()
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise
        self._journal_synced = time.monotonic()
        self._reserve = reserve_bytes
        self._free = free if free is not None else free_bytes
        self._last_t = -math.inf
        self._labels: Labels | None = None
        self._thermal: ThermalData | None = None
        self._projector: Any = None  # cv2.VideoWriter of projector.mkv once set_projector is called
        self._projector_times: list[float] = []
        self._files: dict[str, bytes] = {}
        self.frames_written = 0
        self.frames_lost = 0

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
        if (free := self._free(self._tmp)) < self._reserve:
            raise DiskFull(self._tmp, free)
        if self._video.write(np.ascontiguousarray(frame)) is False:  # OpenCV >= 5 says; 4.x returns None
            raise DiskFull(self._tmp, self._free(self._tmp))
        self._times.append(t)
        self._last_t = t
        self.frames_written += 1
        self._journal.write(f"{t:.6f}\n")
        self._journal.flush()  # in the kernel's hands: a killed process loses nothing
        if (now := time.monotonic()) - self._journal_synced >= JOURNAL_SYNC_S:  # on the disk: a power cut loses <= this
            os.fsync(self._journal.fileno())
            self._journal_synced = now

    def set_labels(self, labels: Labels) -> None:
        self._labels = labels

    def set_projector(self, width: int, height: int, fps: float) -> None:
        """Record the projector stream too (``projector.mkv``, gray8: the touch path predicts from grey light)."""
        if self._projector is not None:
            raise ValueError("the projector stream is already open")
        self._projector = cv2.VideoWriter(
            str(self._tmp / "projector.mkv"), cv2.VideoWriter_fourcc(*"FFV1"), fps, (width, height), isColor=False
        )
        if not self._projector.isOpened():
            raise RuntimeError("OpenCV cannot write FFV1/Matroska here (needs its FFmpeg backend)")
        self._meta["projector"] = {"width": width, "height": height, "fps": fps, "pixel_format": "gray8"}

    def add_projector_frame(self, t: float, frame: np.ndarray) -> None:
        """Append what the projector showed from ``t`` on (seconds on the camera's clock; must not go backwards)."""
        if self._projector is None:
            raise ValueError("call set_projector first")
        info = self._meta["projector"]
        if frame.shape[:2] != (info["height"], info["width"]) or frame.dtype != np.uint8:
            raise ValueError(f"projector frame is {frame.shape} {frame.dtype}, stream is {info['width']}x{info['height']} uint8")
        if not math.isfinite(t) or (self._projector_times and t < self._projector_times[-1]):
            raise ValueError(f"projector frame time {t} is not finite or goes backwards")
        if (free := self._free(self._tmp)) < self._reserve:
            raise DiskFull(self._tmp, free)
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame
        if self._projector.write(np.ascontiguousarray(gray)) is False:
            raise DiskFull(self._tmp, self._free(self._tmp))
        self._projector_times.append(t)

    def add_file(self, name: str, data: bytes) -> None:
        """Keep one more file in the recording (a projector calibration beside its stream), written durably on
        close. Only a plain name that none of the format's own files uses."""
        if Path(name).name != name or name in OWN_FILES or name.startswith("."):
            raise ValueError(f"{name!r} is not a plain file name free in a recording")
        self._files[name] = bytes(data)

    def set_thermal(self, thermal: ThermalData, fps: float) -> None:
        self._thermal = thermal
        self._meta["thermal"] = {"width": 32, "height": 24, "fps": fps}

    @property
    def projector_frames(self) -> int:
        """Projector frames kept (after ``close``: those ``projector.mkv`` holds)."""
        return len(self._projector_times)

    @property
    def seconds(self) -> float:
        """The time of the last frame kept (0 before the first)."""
        return self._times[-1] if self._times else 0.0

    def close(self) -> Path:
        """Give back the room set aside, finish the files with the frame times cut to the frames the video
        holds, make them durable and move the recording into place.

        If that fails (no frame reached the disk, or no room even so) the temp dir is removed and the error
        raised: nothing half is left. ``frames_lost`` says how many frames the cut took off.
        """
        self._set_aside.unlink(missing_ok=True)  # first: FFmpeg's release writes its last cluster and index
        self._journal.close()
        self._video.release()
        if self._projector is not None:
            self._projector.release()
        try:
            held = frames_held(self._tmp / "camera.mkv", len(self._times))
            self.frames_lost = len(self._times) - held
            del self._times[held:]
            self.frames_written = held
            if held == 0:
                raise OSError(errno.ENOSPC, "no frame reached the disk", str(self.path))
            if self._projector is not None:
                del self._projector_times[frames_held(self._tmp / "projector.mkv", len(self._projector_times)) :]
            self._finish_files()
            for name in (JOURNAL_META, JOURNAL_TIMES):
                (self._tmp / name).unlink(missing_ok=True)
            if self.path.exists() and self._overwrite:
                shutil.rmtree(self.path)
            os.replace(self._tmp, self.path)
            fsync_path(self.path.parent)
        except BaseException:
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise
        return self.path

    def _finish_files(self) -> None:
        write_durably(self._tmp / "camera_ts.txt", "".join(f"{t:.6f}\n" for t in self._times).encode())
        if self._projector is not None:
            write_durably(self._tmp / "projector_ts.txt", "".join(f"{t:.6f}\n" for t in self._projector_times).encode())
            fsync_path(self._tmp / "projector.mkv")
        write_durably(self._tmp / "meta.json", (json.dumps(self._meta, indent=1) + "\n").encode())
        if self._labels is not None:
            write_durably(self._tmp / "labels.json", (json.dumps(self._labels.to_json()) + "\n").encode())
        if self._thermal is not None:
            arrays: dict[str, np.ndarray] = {"t": self._thermal.t, "celsius": self._thermal.celsius}
            if self._thermal.eeprom is not None:
                arrays["eeprom"] = self._thermal.eeprom
            if self._thermal.ram is not None:
                arrays["ram"] = self._thermal.ram
            buffer = io.BytesIO()
            np.savez_compressed(buffer, **arrays)
            write_durably(self._tmp / "thermal.npz", buffer.getvalue())
        for name, data in self._files.items():
            write_durably(self._tmp / name, data)
        fsync_path(self._tmp / "camera.mkv")
        fsync_path(self._tmp)

    def abort(self) -> None:
        self._journal.close()
        self._video.release()
        if self._projector is not None:
            self._projector.release()
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


@dataclass(frozen=True)
class Recovered:
    """One interrupted take found beside a target: where it went (``None``: nothing usable, removed) and how much."""

    temp: Path
    path: Path | None
    frames: int


def recover_interrupted(parent: Path, *, alive: Callable[[int], bool] | None = None) -> list[Recovered]:
    """Finish the takes under ``parent`` whose writing process died (SIGKILL, a power cut, the OOM killer).

    A take writes into a hidden temp dir with a journal of its meta and frame times (:class:`RecordingWriter`).
    For each such dir whose writer is gone: the room set aside is given back, the times are cut to the frames
    the video holds (FFmpeg's last cluster dies with it: up to 5 s), the format's files are written durably and
    the dir is renamed to its target's name (``NAME-recovered``, ``-recovered-2``, ... when that exists). A take
    without a decodable frame is removed. Temp dirs without a journal (an older writer's) are left alone."""
    is_alive = alive if alive is not None else _process_alive
    found: list[Recovered] = []
    for temp in sorted(parent.glob(".*")):
        journal = temp / JOURNAL_META
        if not temp.is_dir() or not journal.is_file():
            continue
        try:
            header = json.loads(journal.read_text(encoding="utf-8"))
            pid, target, meta = int(header["pid"]), str(header["target"]), dict(header["meta"])
        except (OSError, ValueError, KeyError, TypeError):
            continue  # a journal cut mid-write: its take had no frame yet
        if is_alive(pid):
            continue  # still being written
        (temp / SET_ASIDE_NAME).unlink(missing_ok=True)
        times = _journal_times(temp / JOURNAL_TIMES)
        held = frames_held(temp / "camera.mkv", len(times)) if (temp / "camera.mkv").is_file() else 0
        if held == 0:
            shutil.rmtree(temp, ignore_errors=True)
            found.append(Recovered(temp, None, 0))
            continue
        meta.pop("projector", None)  # its stream's times were kept only in memory: the camera take stands alone
        for name in ("projector.mkv", JOURNAL_TIMES, JOURNAL_META):
            (temp / name).unlink(missing_ok=True)
        write_durably(temp / "camera_ts.txt", "".join(f"{t:.6f}\n" for t in times[:held]).encode())
        write_durably(temp / "meta.json", (json.dumps(meta, indent=1) + "\n").encode())
        destination = _free_name(parent, target)
        os.replace(temp, destination)
        fsync_path(parent)
        found.append(Recovered(temp, destination, held))
    return found


def _journal_times(path: Path) -> list[float]:
    """The journal's frame times up to its first line that is not a whole number (a line cut by the kill)."""
    times: list[float] = []
    try:
        text = path.read_text(encoding="ascii", errors="replace")
    except OSError:
        return times
    for line in text.split("\n")[:-1]:  # the last piece has no newline: cut mid-write, or empty
        try:
            t = float(line)
        except ValueError:
            break
        if not math.isfinite(t) or (times and t <= times[-1]):
            break
        times.append(t)
    return times


def _free_name(parent: Path, target: str) -> Path:
    candidate = parent / f"{target}-recovered"
    n = 2
    while candidate.exists():
        candidate = parent / f"{target}-recovered-{n}"
        n += 1
    return candidate


def _process_alive(pid: int) -> bool:
    """Whether ``pid`` runs: a zombie (killed, not yet reaped by its parent) has stopped writing for good."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # someone else's process
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True  # no /proc: trust kill(0)
    return state not in ("Z", "X")
