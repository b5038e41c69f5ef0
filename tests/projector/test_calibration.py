"""The calibration map, Gray-code + phase decoding, and the whole procedure against the simulator."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.lab.projector.calibrate import run_calibration, truth_error
from feelium.skin.projector_map import CalibrationError, default_calibration, load_calibration, sample
from feelium.projector.config import CalibrationConfig
from feelium.lab.projector.graycode import PatternPlan, decode, make_patterns, smooth_map
from feelium.sim.projection import FisheyeWarp, ProjectedLight, SimPatternCapture
from feelium.sim.scene import Session
from tests.projector.helpers import CAMERA, PROJECTOR, ROI, truth_calibration


def test_patterns_decode_to_themselves():
    """Fed the projector's own images (an identity 'camera'), the decoder returns every pixel's coordinates."""
    plan = PatternPlan(200, 120, 8, 32, 8)
    captures = {p.name: p.image.astype(np.float32) for p in make_patterns(plan)}
    decoded = decode(captures, plan, min_contrast=10)
    assert decoded.valid.all()
    xs, ys = np.meshgrid(np.arange(200), np.arange(120))
    assert np.abs(decoded.proj_x - xs).max() < 0.05
    assert np.abs(decoded.proj_y - ys).max() < 0.05


def test_pattern_sequence_uses_opencv_gray_code_pairs():
    plan = PatternPlan(1280, 720, 8, 32, 8)
    names = [p.name for p in make_patterns(plan)]
    assert names[:7] == ["white", "black", "level_64", "level_128", "level_192", "gray_x0", "gray_x0_inv"]
    assert len(names) == 2 + 3 + 2 * (8 + 7) + 2 * 8
    with pytest.raises(ValueError, match="phase period"):
        make_patterns(PatternPlan(1280, 720, 16, 16, 8))


@given(st.floats(-3, 3), st.floats(-3, 3), st.floats(0, 500))
def test_smoothing_is_unbiased_for_a_plane_even_at_the_border(gx, gy, c):
    h, w = 40, 50
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    plane = c + gx * xs + gy * ys
    valid = np.zeros((h, w), bool)
    valid[5:35, 8:40] = True
    out = smooth_map(plane.astype(np.float32), valid, 1.5)
    assert np.isnan(out[~valid]).all()
    assert np.abs(out[valid] - plane[valid]).max() < 2e-3 * (1 + abs(c) + 50 * (abs(gx) + abs(gy)))


def test_save_load_round_trip(tmp_path):
    cal = truth_calibration()
    path = cal.save(tmp_path / "cal.npz")
    back = load_calibration(path)
    assert back.camera_size == CAMERA and back.projector_size == PROJECTOR and back.roi == ROI
    assert np.array_equal(np.isnan(back.proj_x), np.isnan(cal.proj_x))
    assert np.nanmax(np.abs(back.proj_x - cal.proj_x)) == 0.0


def test_load_names_the_bad_file(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(CalibrationError, match="bad.npz"):
        load_calibration(bad)
    with pytest.raises(CalibrationError, match="missing.npz"):
        load_calibration(tmp_path / "missing.npz")


def test_roi_must_fit_the_camera():
    with pytest.raises(CalibrationError, match="roi"):
        default_calibration((640, 480), (600, 0, 100, 100), PROJECTOR)


def test_inverse_map_round_trips_the_fisheye_within_a_pixel():
    cal = truth_calibration()
    inv_x, inv_y = cal.projector_to_camera()
    ys, xs = np.mgrid[ROI[1] + 2 : ROI[1] + ROI[3] - 2 : 7, ROI[0] + 2 : ROI[0] + ROI[2] - 2 : 7]
    px, py = cal.proj_x[ys, xs], cal.proj_y[ys, xs]
    back_x, back_y = sample(inv_x, px, py), sample(inv_y, px, py)
    err = np.hypot(back_x - xs, back_y - ys)
    assert np.percentile(err, 95) < 0.5 and err.max() < 1.5
    # Projector pixels far outside the patch have no camera position.
    assert np.isnan(inv_x[5, 5]) and np.isnan(inv_x[700, 1270])


@pytest.mark.slow
def test_sim_calibration_recovers_the_true_map_within_one_pixel():
    warp = FisheyeWarp()
    light = ProjectedLight(warp, CAMERA)
    capture = SimPatternCapture(Session("calib"), light, np.random.default_rng(3))
    result = run_calibration(capture, CalibrationConfig(), PROJECTOR, source="sim")
    truth_x, truth_y = warp.truth_map(*CAMERA)
    error = truth_error(result.calibration, truth_x, truth_y)
    assert result.summary["coverage"] > 0.97
    assert error["within_1px"] == 1.0 and error["max"] < 1.0
    assert error["median"] < 0.2
    assert result.calibration.black_level == pytest.approx(light.optics.black, abs=0.005)
    assert result.calibration.gamma == pytest.approx(light.optics.gamma, abs=0.05)
    assert result.summary["fit_residual_px"]["median"] < 0.5
    json.dumps(result.summary)  # machine-readable as it stands


def test_a_calibration_file_is_held_once_however_many_parts_load_it(tmp_path):
    """The renderer, the touch annotation and the light predictor each loaded their own 2.4 MB copy before."""
    from feelium.skin.projector_map import load_shared

    path = truth_calibration().save(tmp_path / "cal.npz")
    first = load_shared(path)
    assert load_shared(tmp_path / "." / "cal.npz") is first
    for array in (first.proj_x, first.proj_y):
        assert array.dtype == np.float32 and array.shape == (CAMERA[1], CAMERA[0])
        assert not array.flags.writeable  # shared: no part may change what the others see
        with pytest.raises(ValueError):
            array[0, 0] = 1.0
    assert load_calibration(path).proj_x.flags.writeable  # a plain load stays the caller's own
    moved = default_calibration(CAMERA, ROI, PROJECTOR)
    moved.save(path)  # recalibrated: the new file is read, not the map in memory
    again = load_shared(path)
    assert again is not first and again.source == "default"
    with pytest.raises(CalibrationError):
        load_shared(tmp_path / "missing.npz")


def test_the_inverse_is_fitted_once_per_map_and_a_pickled_map_inverts_alike() -> None:
    """The renderer, touch's light predictors and the probe all invert the one shared map: its least squares runs once
    (its design matrix was the daemon's start-up memory peak, session 25), and a map pickled for a worker process
    (without its lock) gives the same inverse."""
    calibration = truth_calibration()
    first = calibration.projector_to_camera()
    fitted = calibration._inverse_fit()
    assert calibration._inverse_fit()[0] is fitted[0]  # kept, not fitted again
    copy = pickle.loads(pickle.dumps(calibration))
    for ours, theirs in zip(first, copy.projector_to_camera()):
        np.testing.assert_array_equal(ours, theirs)
    assert copy._inverse_lock is not calibration._inverse_lock
