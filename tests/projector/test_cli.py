"""`feelium calibrate projector --sim --json` and `feelium bench projector` as a user runs them."""

import json

import pytest

from feelium.cli import main
from feelium.projector.calibration import load_calibration


@pytest.mark.slow
def test_calibrate_sim_json_reports_error_to_truth_and_saves_the_map(tmp_path, capsys):
    out = tmp_path / "cal.npz"
    assert main(["calibrate", "projector", "--sim", "--json", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["coverage"] > 0.97
    assert summary["truth_error_px"]["max"] < 1.0
    assert summary["saved"] == str(out)
    assert load_calibration(out).source == "sim"


def test_calibrate_saves_beside_the_config_by_default(tmp_path, capsys, monkeypatch):
    config = tmp_path / "feelium.toml"
    config.write_text('[projector.calibration]\nfile = "cal.npz"\nframes_per_pattern = 1\nsettle_frames = 0\n')
    monkeypatch.chdir("/")
    assert main(["calibrate", "projector", "--sim", "--config", str(config)]) == 0
    text = capsys.readouterr().out
    assert "coverage of the sensitive patch" in text and (tmp_path / "cal.npz").exists()


def test_bench_prints_a_table_and_writes_json(tmp_path, capsys):
    report_path = tmp_path / "bench.json"
    assert main(["bench", "projector", "--frames", "3", "--json", str(report_path)]) == 0
    assert "render_everything" in capsys.readouterr().out
    report = json.loads(report_path.read_text())
    assert set(report["rows"]) == {"baseline_resize", "render_avatar", "render_typical", "render_everything", "backlight_gain"}
    assert report["rows"]["baseline_resize"]["ratio_to_baseline"] == 1.0
