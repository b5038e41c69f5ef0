"""A recording's projector stream turned into the light the daemon would predict for each camera exposure."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from feelium.lab.touch.recorded_light import CALIBRATION_FILE, RecordedLight, find_calibration, recorded_light
from feelium.projector.config import ProjectorConfig
from feelium.recording import Recording, RecordingError, RecordingWriter
from feelium.skin.projector_map import ProjectorMap
from feelium.touch.config import TouchConfig


class _Grey:
    """A stand-in predictor: a projector frame's light is its grey level over 100, everywhere."""

    def __init__(self) -> None:
        self.calls = 0

    def gain(self, frame: np.ndarray) -> np.ndarray:
        self.calls += 1
        return np.full((6, 8), float(frame.mean()) / 100.0, np.float32)


def _stream(step_t: float, fps: float = 30.0, end: float = 2.0):
    for k in range(int(end * fps)):
        t = k / fps
        yield t, np.full((4, 4), 200 if t >= step_t else 100, np.uint8)


def test_each_exposure_sees_only_what_was_shown_before_it_and_the_latency():
    config = TouchConfig()
    predictor = _Grey()
    light = RecordedLight(_stream(1.0), predictor.gain, config)
    assert light(-0.5) == {}  # nothing shown yet
    steady = light(0.5)
    assert steady["projected_light"] == pytest.approx(np.ones((6, 8)), abs=1e-6)
    assert float(steady["projected_spread"].max()) == pytest.approx(0.0, abs=1e-6)
    # The step is shown at 1.0 s; the membrane lights up projector_latency_s later: an exposure centred
    # just after 1.0 s still integrates the old frame, and frames shown after a camera frame are not known.
    assert light(1.0 + config.projector_latency_s - config.camera_exposure_s)["projected_light"] == pytest.approx(1.0, abs=1e-6)
    late = 1.0 + config.projector_latency_s + config.projector_latency_sigma_s + config.camera_exposure_s
    assert float(light(late + 0.01)["projected_light"].mean()) == pytest.approx(2.0, abs=1e-6)
    assert predictor.calls <= sum(1 for k in range(60) if k / 30.0 <= late + 0.01)  # each frame predicted at most once


def test_the_calibration_is_found_beside_the_trials_and_not_above_the_dataset(tmp_path):
    root = tmp_path / "ds"
    trial = root / "faceon-face" / "s1" / "s1-tap-001"
    trial.mkdir(parents=True)
    assert find_calibration(trial, root) is None
    (tmp_path / CALIBRATION_FILE).write_bytes(b"")  # above the dataset: not the dataset's
    assert find_calibration(trial, root) is None
    (root / "faceon-face" / CALIBRATION_FILE).write_bytes(b"")
    assert find_calibration(trial, root) == (root / "faceon-face" / CALIBRATION_FILE).resolve()
    (trial / CALIBRATION_FILE).write_bytes(b"")
    assert find_calibration(trial, root) == (trial / CALIBRATION_FILE).resolve()


def test_a_map_copied_from_the_blimp_under_its_own_name_is_found_too(tmp_path):
    """`calibrate projector --config` saves `projector_calibration.npz`; copied beside the trials it needs no renaming."""
    trial = tmp_path / "s1" / "s1-tap-001"
    trial.mkdir(parents=True)
    (tmp_path / "projector_calibration.npz").write_bytes(b"")
    assert find_calibration(trial, tmp_path) == (tmp_path / "projector_calibration.npz").resolve()


def _calibration_recording(folder, session: str) -> None:
    """A calibration recording as `find_calibration` sees it: its meta (the frames are only read to fit)."""
    folder.mkdir(parents=True)
    meta = {"format": "feelium.recording", "version": 1, "session": session, "purpose": "projector-calibration"}
    (folder / "meta.json").write_text(json.dumps(meta))


def test_a_calibration_recording_of_the_trials_own_session_is_chosen_over_the_first_by_name(tmp_path):
    """The recording format fits the map of "the recordings beside it (same session)": a dataset laid out with
    one calibration recording per session side by side gives each trial its own projector's map."""
    _calibration_recording(tmp_path / "calibration-a", "monday")
    _calibration_recording(tmp_path / "calibration-b", "tuesday")
    trial = tmp_path / "tuesday" / "tap-001"
    trial.mkdir(parents=True)
    assert find_calibration(trial, tmp_path, "tuesday") == (tmp_path / "calibration-b").resolve()
    assert find_calibration(trial, tmp_path, "monday") == (tmp_path / "calibration-a").resolve()
    # No calibration of the trial's session: the first by name, as before (a calibration run names no session).
    assert find_calibration(trial, tmp_path, "wednesday") == (tmp_path / "calibration-a").resolve()
    assert find_calibration(trial, tmp_path) == (tmp_path / "calibration-a").resolve()


def _uniform_map(projector_size: tuple[int, int], camera_size: tuple[int, int] = (64, 48)) -> ProjectorMap:
    """Every camera pixel sees the projector's centre: enough for the light of a flat projector frame."""
    w, h = camera_size
    px, py = projector_size
    return ProjectorMap(camera_size, projector_size, (0, 0, w, h), np.full((h, w), px / 2, np.float32),
                        np.full((h, w), py / 2, np.float32), source="test")  # fmt: skip


def _trial_with_stream(path, projector_size: tuple[int, int]) -> Recording:
    with RecordingWriter(path, name=path.name, width=64, height=48, fps=15.0, session="s1") as writer:
        writer.set_projector(*projector_size, 15.0)
        writer.add_projector_frame(0.0, np.full(projector_size[::-1], 255, np.uint8))
        for i in range(3):
            writer.add_frame(0.1 + i / 15.0, np.full((48, 64), 120, np.uint8))
    return Recording(path)


def test_a_stream_from_a_projector_of_another_resolution_is_predicted_at_its_own_size(tmp_path):
    """A recording made with another blimp's projector states its size in meta.projector; the configured
    [projector] size (this blimp's 1280x720) used to refuse every one of its frames with a traceback."""
    size = (960, 540)
    trial = _trial_with_stream(tmp_path / "ds" / "tap-001", size)
    _uniform_map(size).save(tmp_path / "ds" / CALIBRATION_FILE)
    optics = ProjectorConfig()
    assert (optics.width, optics.height) != size
    light = recorded_light(trial, tmp_path / "ds", optics, TouchConfig())
    assert light is not None
    shown = light(0.1 + 2 / 15.0)["projected_light"]
    assert float(shown.mean()) > 1.0  # full white is brighter than the flat grey the reference stands for
    # A map of another projector than the stream's is not this recording's: one line naming both sizes.
    wrong = tmp_path / "wrong.npz"
    _uniform_map((1280, 720)).save(wrong)
    with pytest.raises(RecordingError, match=r"960x540.*1280x720"):
        recorded_light(trial, tmp_path / "ds", optics, TouchConfig(), wrong)


def test_a_latency_measured_by_the_calibration_is_the_one_the_exposures_are_mixed_with(tmp_path):
    """A projector 80 ms late (measured from its calibration recording, kept in the map): replay mixes each exposure
    with that, not [touch] projector_latency_s (33 ms), so a switch reaches the prediction when it reached the skin."""
    size = (128, 72)
    trials = []
    for name, latency in (("assumed", None), ("measured", 0.080)):
        path = tmp_path / name / "tap-001"
        with RecordingWriter(path, name=path.name, width=64, height=48, fps=15.0, session="s1") as writer:
            writer.set_projector(*size, 30.0)
            writer.add_projector_frame(0.0, np.zeros(size[::-1], np.uint8))
            writer.add_projector_frame(1.0, np.full(size[::-1], 255, np.uint8))  # the switch
            writer.add_frame(0.1, np.full((48, 64), 120, np.uint8))
        dataclasses.replace(_uniform_map(size), latency_s=latency, latency_sigma_s=latency and 0.001).save(
            tmp_path / name / CALIBRATION_FILE
        )
        trials.append(recorded_light(Recording(path), tmp_path / name, ProjectorConfig(), TouchConfig()))
    # The exposure centred on 1.06 s (30 ms): lit 1.012-1.042 s at 33 ms, all white; 0.965-0.995 s at 80 ms, all black.
    assumed, measured = (float(light(1.06)["projected_light"].mean()) for light in trials)  # type: ignore[misc]
    assert assumed > 1.0 and measured < 0.1
