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

import functools
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from feelium.lab.projector.from_recording import calibrate_recording
from feelium.projector.config import CalibrationConfig, ProjectorConfig
from feelium.projector.recorded import StreamLight, stream_light, stream_optics
from feelium.recording import CALIBRATION_FILE, CALIBRATION_PURPOSE, Recording, RecordingError, find_calibration, find_recordings
from feelium.skin.projector_map import CalibrationError, ProjectorMap, load_calibration
from feelium.touch.config import TouchConfig
from feelium.touch.geometry import LightGrids
from feelium.touch.projected import ExposureLight, ProjectorHistory, history_window_s, touch_with_latency


class RecordedLight:
    """Per camera frame time: the pipeline's ``projected_light``/``projected_spread`` keyword arguments."""

    def __init__(
        self,
        frames: Iterator[tuple[float, np.ndarray]],
        predict: Callable[[np.ndarray], np.ndarray],
        config: TouchConfig,
        predictor_for: StreamLight | None = None,
    ) -> None:
        """``predict(frame)``: a projector frame's light at the camera frame's size.
        ``predictor_for(frame size, box, average_of)``: the same predictor at another size over a box, for
        :meth:`use_grids` (:func:`feelium.projector.recorded.stream_light`)."""
        self._frames = frames
        self._next: tuple[float, np.ndarray] | None = next(frames, None)
        self._seq = 0
        self._config = config
        self._predictor_for = predictor_for
        self._history = ProjectorHistory(history_window_s(config))
        self._light = ExposureLight(lambda frame, _out: predict(frame), config)  # allocates: lab replay
        self._fine: dict[str, object] = {}

    def use_grids(self, grids: LightGrids | None) -> None:
        """Predict as the daemon does for a pipeline that detects coarser (:attr:`TouchPipeline.light_grids`): on
        the detection grid, and at the working resolution in the fine pass's windows (``fine_light``). The frame
        predictor has no window of its own: the lab predicts the whole box and cuts the window (the same values)."""
        if grids is None or self._predictor_for is None:
            return
        fine = None if grids.fine is None else self._predictor_for(*grids.fine)
        coarse = self._predictor_for(*grids.coarse, grids.average_of)
        self._light = ExposureLight(lambda frame, _out: coarse(frame), self._config, None if fine is None else fine.window)
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
    light = stream_light(stream_optics(projector, recording, cal, path), cal)
    touch = touch_with_latency(touch, cal)  # the projector's measured latency, not the assumed one, when it has one
    camera = recording.meta.camera
    return RecordedLight(recording.projector_frames(), light((camera.width, camera.height)), touch, light)


def replay_map(root: Path, projector: ProjectorConfig, touch: TouchConfig, out: Path) -> Path | None:
    """For ``feelium run --replay ROOT``: the calibration recording the replayed streams find beside them, fitted
    and saved as a map file under ``out`` (the daemon loads saved maps; it does not load the lab code that fits
    them). None when no stream's lookup finds a calibration recording (each has a saved map, or none: the touch
    service names that one in health).

    ValueError when the streams find several calibration recordings, or some a recording and some a saved map: one
    map for the whole replay would give some recordings another projector's map."""
    found: set[Path | None] = set()
    for path in find_recordings(root):
        recording = Recording(path)
        if recording.has_projector and recording.meta.raw.get("purpose") != CALIBRATION_PURPOSE:
            found.add(find_calibration(path, root, recording.meta.session))
    fitted = sorted(path for path in found if path is not None and path.is_dir())
    if not fitted:
        return None
    if len(found) > 1:
        names = ", ".join(sorted(str(path) for path in found if path is not None))
        raise ValueError(
            f"the replayed streams find {len(found)} different projector calibrations ({names}): fit each with "
            "`feelium calibrate projector` and replay each set of recordings with its map (--projector-calibration)"
        )
    cal = fitted_calibration(fitted[0].resolve(), projector.calibration, touch.projector_latency_s, touch.camera_exposure_s)
    saved = out / CALIBRATION_FILE
    cal.save(saved)
    return saved
