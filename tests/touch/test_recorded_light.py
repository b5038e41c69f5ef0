"""A recording's projector stream turned into the light the daemon would predict for each camera exposure."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.lab.touch.recorded_light import CALIBRATION_FILE, RecordedLight, find_calibration
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
    light = RecordedLight(_stream(1.0), predictor, config)  # type: ignore[arg-type]
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
