"""The projected light of every camera exposure, from a recording's projector stream, as the daemon predicts it.

A recording made while the skin showed a face carries what the projector showed (``projector.mkv`` with
each frame's display time, docs/recording-format.md). Replaying it without that knowledge judges a pipeline
that is blind to the face the daemon chose itself, so ``replay``/``eval`` feed the pipeline the same
``projected_light`` and ``projected_spread`` the touch service gives it on the blimp: the recent projector
frames (:class:`feelium.touch.projected.ProjectorHistory`, the daemon's window) mixed over each camera
exposure with the latency's spread (:class:`feelium.touch.projected.ExposureLight`). The one difference is
the source of a frame's light: the daemon predicts it from the grey skin canvas it drew
(:mod:`feelium.projector.canvaslight`), a recording only holds the projector's frame, so the frame
predictor (:class:`feelium.projector.backlight.BacklightPredictor`, the reference the canvas predictor is
checked against) is used, through the camera-to-projector calibration found for the recording: a saved map, or a calibration recording
beside the trials, fitted offline (:mod:`feelium.lab.projector.from_recording`). When that calibration measured the
projector's latency (:mod:`feelium.lab.projector.latency`), the exposures are mixed with it instead of ``[touch]
projector_latency_s``: a projector slower than the blimp's is replayed as it lit the membrane, without hand-tuning.
"""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from feelium.lab.projector.from_recording import PURPOSE, calibrate_recording
from feelium.projector.backlight import BacklightPredictor
from feelium.projector.config import CalibrationConfig, ProjectorConfig
from feelium.recording import Recording, RecordingError
from feelium.skin.projector_map import CalibrationError, ProjectorMap, load_calibration
from feelium.touch.config import TouchConfig
from feelium.touch.geometry import LightGrids
from feelium.touch.projected import ExposureLight, ProjectorHistory, history_window_s, touch_with_latency

CALIBRATION_FILE = "projector-calibration.npz"  # a map saved by ProjectorMap.save, found beside the trials
# The name `feelium calibrate projector` saves on the blimp (`[projector.calibration] file`): a map copied from
# the blimp beside the trials is found under it too.
CALIBRATION_FILES = (CALIBRATION_FILE, "projector_calibration.npz")


class RecordedLight:
    """Per camera frame time: the pipeline's ``projected_light``/``projected_spread`` keyword arguments."""

    def __init__(
        self,
        frames: Iterator[tuple[float, np.ndarray]],
        predictor: BacklightPredictor,
        config: TouchConfig,
        predictor_for: Callable[[tuple[int, int], int], BacklightPredictor] | None = None,
    ) -> None:
        """``predictor_for(frame size, average_of)``: the same predictor at another size, for :meth:`use_grids`."""
        self._frames = frames
        self._next: tuple[float, np.ndarray] | None = next(frames, None)
        self._seq = 0
        self._config = config
        self._predictor_for = predictor_for
        self._history = ProjectorHistory(history_window_s(config))
        self._light = ExposureLight(lambda frame, _out: predictor.gain(frame), config)  # allocates: lab replay
        self._fine: dict[str, object] = {}

    def use_grids(self, grids: LightGrids | None) -> None:
        """Predict as the daemon does for a pipeline that detects coarser (:attr:`TouchPipeline.light_grids`): on
        the detection grid, and at the working resolution in the fine pass's windows (``fine_light``). The frame
        predictor has no window of its own: the lab predicts the whole box and cuts the window (the same values)."""
        if grids is None or self._predictor_for is None:
            return
        size, (x, y, w, h) = grids.coarse
        coarse = self._predictor_for(size, grids.average_of)
        window = None
        if grids.fine is not None:
            fine_size, (fx, fy, fw, fh) = grids.fine
            full = self._predictor_for(fine_size, 1)

            def window(frame: np.ndarray, rows: slice, cols: slice) -> np.ndarray:
                return full.gain(frame)[fy : fy + fh, fx : fx + fw][rows, cols]

        self._light = ExposureLight(lambda frame, _out: coarse.gain(frame)[y : y + h, x : x + w], self._config, window)
        self._fine = {"fine_light": self._light.window}

    def __call__(self, t: float) -> dict[str, np.ndarray]:
        """What the daemon would know at camera time ``t``: every projector frame shown up to ``t``."""
        while self._next is not None and self._next[0] <= t:
            self._history.record(self._next[0], self._seq, self._next[1])
            self._seq += 1
            self._next = next(self._frames, None)
        mixed = self._light(self._history.frames(), t)
        if mixed is None:
            return {}
        light, spread = mixed  # reused by the next call: the pipeline reads them within this frame
        return {"projected_light": light, "projected_spread": spread, **self._fine}


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
        if isinstance(meta, dict) and meta.get("purpose") == PURPOSE:
            session = meta.get("session")
            found.append((child, session if isinstance(session, str) else None))
    return tuple(found)


@functools.lru_cache(maxsize=8)
def fitted_calibration(path: Path, config: CalibrationConfig, latency_s: float, exposure_s: float) -> ProjectorMap:
    """The map fitted from a calibration recording (with the latency it measures, when it can), once per recording
    however many trials use it."""
    try:
        return calibrate_recording(Recording(path), config, latency_s, exposure_s).calibration
    except ValueError as exc:
        raise RecordingError(path, f"cannot fit the projector calibration from it: {exc}") from exc


def recorded_light(
    recording: Recording, root: Path, projector: ProjectorConfig, touch: TouchConfig, calibration: Path | None = None
) -> RecordedLight | None:
    """The light feed of ``recording``, or None when it has no projector stream.

    A recording with a projector stream but no calibration (none given, none beside it) is an error that
    says so: replaying it blind would score a different pipeline from the daemon's without notice.
    """
    if not recording.has_projector:
        return None
    path = calibration if calibration is not None else find_calibration(recording.path, root, recording.meta.session)
    if path is None:
        raise RecordingError(
            recording.path, f"has a projector stream but no projector calibration ({CALIBRATION_FILE} or a calibration recording beside it, "
            "or --projector-calibration)"
        )
    if path.is_dir():  # a calibration recording: fitted offline, as `feelium calibrate projector RECORDING` does
        cal = fitted_calibration(path.resolve(), projector.calibration, touch.projector_latency_s, touch.camera_exposure_s)
    else:
        try:
            cal = load_calibration(path)
        except CalibrationError as exc:
            raise RecordingError(path, str(exc)) from exc
    projector = stream_optics(projector, recording, cal, path)
    touch = touch_with_latency(touch, cal)  # the projector's measured latency, not the assumed one, when it has one
    camera = recording.meta.camera
    predictor = BacklightPredictor(projector, cal, (camera.width, camera.height))
    return RecordedLight(
        recording.projector_frames(), predictor, touch, lambda size, n: BacklightPredictor(projector, cal, size, average_of=n)
    )


def stream_optics(projector: ProjectorConfig, recording: Recording, cal: ProjectorMap, source: Path) -> ProjectorConfig:
    """``projector`` at the size of the projector the recording was made with (``meta.projector``).

    Why: a recording from another blimp's projector has its own resolution, which its meta states and the map
    fitted from its calibration recording shares; the configured ``[projector]`` size is only this blimp's, and
    predicting with it refused every frame of such a stream. A map of another size than the stream is not that
    projector's map: an error that names both."""
    info = recording.meta.raw.get("projector")
    try:
        size = (int(info["width"]), int(info["height"]))  # type: ignore[index]
    except (TypeError, KeyError, ValueError):
        raise RecordingError(recording.path / "meta.json", "projector: expected an object with width and height") from None
    mapped = (int(cal.projector_size[0]), int(cal.projector_size[1]))
    if mapped != size:
        raise RecordingError(
            recording.path, f"its projector stream is {size[0]}x{size[1]}, but the calibration {source} maps a {mapped[0]}x{mapped[1]} projector"
        )
    return dataclasses.replace(projector, width=size[0], height=size[1])
