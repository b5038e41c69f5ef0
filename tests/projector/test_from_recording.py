"""`feelium calibrate projector RECORDING`: the map fitted offline from a recording's own projector stream.

The recordings are made the way a user makes them (`feelium calibrate projector --record DIR`: the live run
wrapped in :class:`RecordingCapture`) against the simulator, whose true map is known.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from feelium.cli import main
from feelium.daemon.config import Config
from feelium.lab.projector.calibrate import run_calibration, truth_error
from feelium.lab.projector.from_recording import PURPOSE, RecordingCapture, Shown, calibrate_recording, flat_frames_response
from feelium.recording import Recording, RecordingError, RecordingWriter
from feelium.sim.projection import FisheyeWarp, ProjectedLight, ProjectorOptics, SimPatternCapture
from feelium.sim.scene import HEIGHT, WIDTH, Session
from feelium.skin.projector_map import load_calibration

pytestmark = pytest.mark.slow
CONFIG = Config()
FAST = replace(CONFIG.projector.calibration, settle_frames=0, frames_per_pattern=1)  # the simulator needs no settling
SIZE = (CONFIG.projector.width, CONFIG.projector.height)
LATENCY = CONFIG.touch.projector_latency_s
EXPOSURE = CONFIG.touch.camera_exposure_s
OPTICS = ProjectorOptics()


def _sim(seed: int = 1) -> tuple[SimPatternCapture, tuple[np.ndarray, np.ndarray]]:
    warp = FisheyeWarp()
    capture = SimPatternCapture(Session("projector-calibration"), ProjectedLight(warp, (WIDTH, HEIGHT)), np.random.default_rng(seed))
    return capture, warp.truth_map(*capture.camera_size)


@pytest.fixture(scope="module")
def own_run(tmp_path_factory):
    """A live calibration of the simulator with its project's own sequence, recorded as `--record` does."""
    capture, _ = _sim()
    recorder = RecordingCapture(capture, tmp_path_factory.mktemp("own") / "session" / "calibration", SIZE, 15.0,
                                session="s", source="synthetic")  # fmt: skip
    live = run_calibration(recorder, FAST, SIZE, source="sim")
    return live, recorder.close()


def test_the_projects_own_sequence_refits_offline_to_the_live_map(own_run):
    live, path = own_run
    recording = Recording(path)
    assert recording.meta.raw["purpose"] == PURPOSE and recording.has_projector
    offline = calibrate_recording(recording, FAST, LATENCY, EXPOSURE)
    assert offline.summary["decoder"] == "own sequence" and offline.summary["patterns_seen"] == live.summary["patterns"]
    # each pattern stamped just after a frame and held past the next: no exposure straddles a switch, so the
    # latency is not measured (refused, said why) and the map is fitted with the config's
    assert offline.summary["latency"]["measured"] is False and "too few to tell" in offline.summary["latency"]["reason"]
    assert offline.calibration.latency_s is None
    np.testing.assert_allclose(offline.calibration.proj_x, live.calibration.proj_x, atol=1e-4, equal_nan=True)
    np.testing.assert_allclose(offline.calibration.proj_y, live.calibration.proj_y, atol=1e-4, equal_nan=True)


def _opencv_gray_code_recording(path: Path) -> tuple[Path, tuple[np.ndarray, np.ndarray]]:
    """OpenCV contrib's full-resolution Gray code (each pattern then its inverse), then its shadow-mask white
    and black and two flat greys: nothing of this project's."""
    capture, truth = _sim(2)
    gray_code = cv2.structured_light.GrayCodePattern.create(width=SIZE[0], height=SIZE[1])
    ok, patterns = gray_code.generate()
    assert ok
    white, black = gray_code.getImagesForShadowMasks(np.zeros(SIZE[::-1], np.uint8), np.zeros(SIZE[::-1], np.uint8))
    greys = [np.full(SIZE[::-1], v, np.uint8) for v in (100, 180)]
    recorder = RecordingCapture(capture, path, SIZE, 15.0, source="synthetic")
    for pattern in [*patterns, white, black, *greys]:
        recorder.show(pattern)
        recorder.capture()
    return recorder.close(), truth


def test_any_binary_sequence_with_inverses_is_decoded_from_the_recorded_frames(tmp_path, capsys):
    path, _ = _opencv_gray_code_recording(tmp_path / "ocv")
    config = tmp_path / "feelium.toml"
    config.write_text("[projector.calibration]\nsettle_frames = 0\nframes_per_pattern = 1\n")
    out = tmp_path / "map.npz"
    # --sim: the simulator's true map is known, so the summary says how far the fitted one is from it
    assert main(["calibrate", "projector", str(path), "--sim", "--config", str(config), "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["decoder"] == "generic binary pairs" and summary["pairs_used"] == 21
    error = summary["truth_error_px"]
    # the finest stripes blur through the fisheye; the code ends where they do (measured: 0.11 / 0.32 px)
    assert error["median"] < 0.5 and error["p95"] < 1.0 and summary["coverage"] > 0.9
    assert load_calibration(out).coverage() == pytest.approx(summary["coverage"], abs=1e-4)
    # the photometric response from the flat frames, against the simulated projector's (gamma 2.2, black 0.035)
    assert summary["gamma"] == pytest.approx(OPTICS.gamma, abs=0.05)
    assert summary["black_level"] == pytest.approx(OPTICS.black, abs=0.01)
    assert load_calibration(out).gamma == pytest.approx(summary["gamma"], abs=1e-3)


def _shown(level_images: dict[int, float]) -> list[Shown]:
    """Flat projector frames seen as flat camera images of the given brightness."""
    return [Shown(np.full((4, 6), v, np.uint8), np.full((8, 8), seen, np.float32), 1) for v, seen in level_images.items()]


def test_the_flat_frames_give_what_they_can_and_no_more():
    valid = np.ones((8, 8), bool)
    model = {v: 10.0 + 200.0 * (0.05 + 0.95 * (v / 255) ** 2.0) for v in (0, 64, 128, 255)}  # room light 10, gamma 2
    black_level, gamma = flat_frames_response(_shown(model), valid)
    assert black_level == pytest.approx(model[0] / model[255]) and gamma == pytest.approx(2.0, abs=0.02)
    # white and black only (OpenCV's shadow masks): the black level, and no gamma made up from nothing
    assert flat_frames_response(_shown({0: model[0], 255: model[255]}), valid) == (pytest.approx(model[0] / model[255]), None)
    assert flat_frames_response(_shown({0: model[0], 128: model[128], 200: 150.0}), valid) == (None, None)  # no white
    assert flat_frames_response(_shown({0: 50.0, 255: 50.0}), valid) == (None, None)  # nothing lit: no figure


def test_a_recording_without_inverse_pairs_or_without_a_projector_stream_is_one_clear_line(tmp_path, capsys):
    capture, _ = _sim(3)
    recorder = RecordingCapture(capture, tmp_path / "flat", SIZE, 15.0, source="synthetic")
    for level in (0, 128, 255):
        recorder.show(np.full(SIZE[::-1], level, np.uint8))
        recorder.capture()
    flat = recorder.close()
    config = tmp_path / "feelium.toml"
    config.write_text("[projector.calibration]\nsettle_frames = 0\n")
    assert main(["calibrate", "projector", str(flat), "--config", str(config), "--out", str(tmp_path / "m.npz")]) == 1
    assert "no binary pattern shown with its inverse" in capsys.readouterr().err
    assert main(["calibrate", "projector", str(flat), "--out", str(tmp_path / "m.npz")]) == 1  # settle_frames 2 of 1
    assert "no projector frame was seen by more than 2 camera frames" in capsys.readouterr().err
    with RecordingWriter(tmp_path / "camera-only", name="c", width=8, height=6, fps=15.0) as writer:
        writer.add_frame(0.0, np.zeros((6, 8), np.uint8))
    with pytest.raises(RecordingError, match="projector.mkv"):
        calibrate_recording(Recording(tmp_path / "camera-only"), FAST, LATENCY, EXPOSURE)


def test_eval_fits_the_map_from_the_calibration_recording_beside_the_trials(own_run):
    from feelium.lab.touch.recorded_light import find_calibration, recorded_light

    calibration = own_run[1]
    dataset = calibration.parent.parent
    trial = calibration.parent / "trial-001"  # a face-on trial: a few camera frames and its projector stream
    with RecordingWriter(trial, name="t", width=640, height=480, fps=15.0) as writer:
        writer.set_projector(*SIZE, 15.0)
        writer.add_projector_frame(0.0, np.full(SIZE[::-1], 200, np.uint8))
        for i in range(3):
            writer.add_frame(0.1 + i / 15.0, np.full((480, 640), 90, np.uint8))
    assert find_calibration(trial, dataset) == calibration
    config = replace(CONFIG.projector, calibration=FAST)
    light = recorded_light(Recording(trial), dataset, config, CONFIG.touch)
    assert light is not None
    lit = light(0.1 + 2 / 15.0)["projected_light"]
    assert lit.shape == (480, 640) and float(np.nanmax(lit)) > 0.5  # the skin lit at 200 where the map covers it


def test_run_replay_gets_the_map_fitted_from_the_calibration_recording_beside_the_streams(own_run, tmp_path):
    """`feelium run --replay`: the daemon loads saved maps only, so the command fits the calibration recording the
    streams find beside them (the same lookup as eval) and hands the daemon that map; never one map for streams
    that find different calibrations."""
    from feelium.lab.touch.recorded_light import replay_map
    from feelium.recording import CALIBRATION_FILE

    dataset = tmp_path / "ds"
    shutil.copytree(own_run[1], dataset / "calibration")
    trial = dataset / "trial-001"
    with RecordingWriter(trial, name="t", width=640, height=480, fps=15.0, session="s") as writer:
        writer.set_projector(*SIZE, 15.0)
        writer.add_projector_frame(0.0, np.full(SIZE[::-1], 200, np.uint8))
        writer.add_frame(0.1, np.full((480, 640), 90, np.uint8))
    projector = replace(CONFIG.projector, calibration=FAST)
    saved = replay_map(dataset, projector, CONFIG.touch, tmp_path)
    assert saved == tmp_path / CALIBRATION_FILE
    offline = calibrate_recording(Recording(dataset / "calibration"), FAST, LATENCY, EXPOSURE).calibration
    loaded = load_calibration(saved)
    for axis in ("proj_x", "proj_y"):
        assert np.array_equal(getattr(loaded, axis), getattr(offline, axis), equal_nan=True)
    (dataset / "other").mkdir()
    shutil.move(trial, dataset / "other" / "trial-001")
    (dataset / "other" / CALIBRATION_FILE).write_bytes(saved.read_bytes())  # this trial's own saved map ...
    assert replay_map(dataset, projector, CONFIG.touch, tmp_path / "none") is None  # ... needs no fitting
    with RecordingWriter(dataset / "trial-002", name="t2", width=640, height=480, fps=15.0, session="s") as writer:
        writer.set_projector(*SIZE, 15.0)
        writer.add_projector_frame(0.0, np.full(SIZE[::-1], 200, np.uint8))
        writer.add_frame(0.1, np.full((480, 640), 90, np.uint8))
    with pytest.raises(ValueError, match="2 different projector calibrations"):
        replay_map(dataset, projector, CONFIG.touch, tmp_path)
