"""``feelium calibrate lens`` recovers a known fisheye from chessboard views rendered through it, and the daemon
serves what it saved."""

from __future__ import annotations

import json
import logging
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from feelium.cameras.config import FrontCameraConfig
from feelium.cameras.lens import FisheyeLens, save_lens
from feelium.cameras.select import front_lens
from feelium.cli import main
from feelium.lab.lens.calibrate import Board, CharucoBoard, LensCalibrationError, calibrate
from feelium.lab.lens.synthetic import TRUTH, recovery_error, synthetic_views

BOARD = Board(9, 6, 0.025)


@pytest.fixture(scope="module")
def views() -> list:
    return synthetic_views(TRUTH, BOARD, 10, seed=2)


def test_a_known_lens_is_recovered_from_rendered_views(views):
    result = calibrate(views, BOARD)
    error = recovery_error(TRUTH, result.lens)
    # measured (seed 2): fx 0.08 %, fy 0.07 %, cx 0.21 px, cy 0.31 px, D 0.001, projection max 0.58 px, RMS 0.069 px
    assert result.lens.source == "calibrated" and len(result.views_used) == 10
    assert result.lens.rms_px < 0.2
    assert error["fx_rel"] < 0.005 and error["fy_rel"] < 0.005
    assert error["cx_px"] < 1.0 and error["cy_px"] < 1.0
    assert error["d_abs_max"] < 0.01
    assert error["projection_px_max"] < 1.5  # where the fitted and the true lens put any direction up to 80 degrees


def test_the_cli_saves_beside_the_config_and_the_daemon_serves_it(views, tmp_path, capsys):
    folder = tmp_path / "board"
    folder.mkdir()
    for i, (_, image) in enumerate(views[:5]):
        cv2.imwrite(str(folder / f"v{i}.png"), image)
    config = tmp_path / "feelium.toml"
    config.write_text('[front_camera]\nlens_file = "lenses/front.json"\n', encoding="utf-8")
    assert main(["calibrate", "lens", str(folder), "--config", str(config), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    saved = Path(summary["saved"])
    assert saved == tmp_path / "lenses" / "front.json" and summary["views_used"] == 5
    cfg = replace(FrontCameraConfig(), lens_file=str(saved), width=320, height=240)
    served = front_lens(cfg, "picamera2")
    assert served.source == "calibrated" and (served.width, served.height) == (320, 240)
    assert served.fx == pytest.approx(summary["lens"]["K"][0][0] / 2) and served.rms_px == summary["rms_px"]


def test_too_few_boards_is_a_clear_error():
    blank = [(f"blank {i}", np.zeros((48, 64), np.uint8)) for i in range(5)]
    with pytest.raises(LensCalibrationError, match="found in 0 view"):
        calibrate(blank, BOARD)


def test_the_served_lens_is_the_sim_lens_in_sim_and_a_labelled_stand_in_without_a_file(tmp_path, caplog):
    cfg = replace(FrontCameraConfig(), lens_file=str(tmp_path / "none.json"))
    assert front_lens(cfg, "sim").source == "sim"
    with caplog.at_level(logging.WARNING):
        nominal = front_lens(cfg, "v4l2")
    assert nominal.source == "nominal" and "feelium calibrate lens" in caplog.text
    (tmp_path / "none.json").write_text("{}", encoding="utf-8")
    assert front_lens(cfg, "v4l2").source == "nominal"  # unreadable: logged, the video keeps going
    save_lens(FisheyeLens(640, 360, 200.0, 200.0, 320.0, 180.0, source="calibrated"), tmp_path / "none.json")
    assert front_lens(cfg, "v4l2").source == "nominal"  # 16:9 calibration for a 4:3 stream: a crop, refused


CHARUCO = CharucoBoard.parse("7x5", 35.0, 26.0, "DICT_4X4_50")


def test_a_charuco_board_counts_views_that_hang_over_the_edge_and_recovers_the_lens():
    """Poses reach 85 degrees off axis with only half the board inside the image; every view with enough
    identified corners counts, including partial ones a chessboard would have to drop."""
    views = synthetic_views(TRUTH, CHARUCO, 8, seed=2)
    seen = [CHARUCO.detect(image) for _, image in views]
    partial = [len(found[0]) for found in seen if found is not None and len(found[0]) < len(CHARUCO.object_points())]
    result = calibrate(views, CHARUCO)
    error = recovery_error(TRUTH, result.lens)
    # measured (seed 2, 8 views): 7 used, 4 of them partial; RMS 0.19 px, fx 0.35 %, projection max 0.82 px
    assert partial and len(result.views_used) >= 6
    assert result.lens.rms_px < 0.3
    assert error["fx_rel"] < 0.005 and error["fy_rel"] < 0.005 and error["cx_px"] < 1.0 and error["cy_px"] < 1.0
    assert error["projection_px_max"] < 1.5


def test_charuco_options_are_checked_and_the_board_is_written_to_print(tmp_path, capsys):
    with pytest.raises(LensCalibrationError, match="markers smaller than the squares"):
        CharucoBoard.parse("7x5", 35.0, 40.0)
    with pytest.raises(LensCalibrationError, match="not an OpenCV ArUco dictionary"):
        CharucoBoard.parse("7x5", 35.0, 26.0, "DICT_NOPE_50")
    with pytest.raises(LensCalibrationError, match="fewer markers"):
        CharucoBoard.parse("12x10", 35.0, 26.0, "DICT_4X4_50")
    png = tmp_path / "board.png"
    assert main(["calibrate", "lens", "--board", "charuco", "--write-board", str(png)]) == 0
    image = cv2.imread(str(png), cv2.IMREAD_GRAYSCALE)
    square_px = round(35.0 / 25.4 * 300)
    assert image.shape == (5 * square_px + 2 * (square_px // 4), 7 * square_px + 2 * (square_px // 4))
    assert CHARUCO.detect(cv2.resize(image, None, fx=0.25, fy=0.25, interpolation=cv2.INTER_AREA)) is not None
    assert "print at 100 %" in capsys.readouterr().out
