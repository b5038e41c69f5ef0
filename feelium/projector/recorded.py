"""The light of a recorded projector stream, predicted for the touch pipeline from the recorded frames.

A recording made while the skin showed a face carries what the projector showed (``projector.mkv`` with each
frame's display time, docs/recording-format.md). Whoever replays it (``feelium replay``/``eval`` in the lab,
``feelium run --replay`` in the daemon) predicts each shown frame's light through the recording's projector map
with the frame predictor (:class:`~feelium.projector.backlight.BacklightPredictor`: the daemon's own projector
predicts from its canvases instead, but a recording holds only the frames). Shared here, below both, so the daemon
never loads lab code and both predict the same light.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from feelium.projector.backlight import BacklightPredictor
from feelium.projector.config import ProjectorConfig
from feelium.recording import Recording, RecordingError
from feelium.skin.projector_map import ProjectorMap

Box = tuple[int, int, int, int]


class BoxedPredictor:
    """A projector frame's light at one camera frame size, over the touch pipeline's box (``[x, y, w, h]``; None:
    the whole frame): the ``predict(frame, out)`` the touch service's exposure mixing takes, and its ``window``
    for the fine pass. The frame predictor has no window of its own: the whole box is predicted and cut (the
    same values; keeping the last frames' light for the next window measured no gain on a face-on tap, 4.10
    against 3.98 ms mean CPU per frame, so it is not kept)."""

    def __init__(self, predictor: BacklightPredictor, box: Box | None) -> None:
        self._predictor = predictor
        self._box = box

    def __call__(self, frame: np.ndarray, _out: np.ndarray | None = None) -> np.ndarray:
        light = self._predictor.gain(frame)
        if self._box is None:
            return light
        x, y, w, h = self._box
        return light[y : y + h, x : x + w]

    def window(self, frame: np.ndarray, rows: slice, cols: slice) -> np.ndarray:
        return self(frame)[rows, cols]


StreamLight = Callable[..., BoxedPredictor]  # (frame size, box=None, average_of=1, finer=None) -> BoxedPredictor


def stream_light(projector: ProjectorConfig, calibration: ProjectorMap) -> StreamLight:
    """Per camera frame size (and the touch pipeline's box, its detection grid's ``average_of``), the predictor of a
    recorded projector frame's light: the touch service's ``projected`` factory for a replayed stream
    (``finer``, the canvas predictor's shared work, has no use here and is ignored)."""

    def for_frame_size(
        size: tuple[int, int], box: Box | None = None, average_of: int = 1, finer: object = None
    ) -> BoxedPredictor:
        return BoxedPredictor(BacklightPredictor(projector, calibration, size, average_of=average_of), box)

    return for_frame_size


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
