"""`feelium calibrate projector --sim --json` and `feelium bench projector` as a user runs them."""

import json

import pytest

from feelium.cli import main
from feelium.skin.projector_map import load_calibration


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


def test_calibrate_records_the_run_under_the_session_of_the_trials_it_calibrates(tmp_path, capsys):
    """replay and eval prefer, among the calibration recordings beside a trial, one of the trial's session."""
    from feelium.recording import Recording

    config = tmp_path / "feelium.toml"
    config.write_text("[projector.calibration]\nframes_per_pattern = 1\nsettle_frames = 0\n")
    rec = tmp_path / "calibration-s2"
    args = ["calibrate", "projector", "--sim", "--config", str(config), "--out", str(tmp_path / "m.npz")]
    assert main([*args, "--record", str(rec), "--session", "s2"]) == 0
    meta = Recording(rec).meta
    assert meta.session == "s2" and meta.raw["purpose"] == "projector-calibration"


def test_bench_prints_a_table_and_writes_json(tmp_path, capsys):
    report_path = tmp_path / "bench.json"
    assert main(["bench", "projector", "--frames", "3", "--stream-seconds", "0.2", "--json", str(report_path)]) == 0
    assert "render_everything" in capsys.readouterr().out
    report = json.loads(report_path.read_text())
    assert set(report["rows"]) == {"baseline_resize", "render_avatar", "render_typical", "render_everything", "backlight_gain", "canvas_light"}
    assert report["rows"]["baseline_resize"]["ratio_to_baseline"] == 1.0
    assert set(report["streams"]) == {"face_video", "still_face"}
    assert all(s["frames"] == 6 and s["max_abs_difference"] == 0 for s in report["streams"].values())


def _fake_report(pred_fp: int, pred_recall: float) -> dict:
    def cond(recall: float, fp: int) -> dict:
        return {"recall": recall, "precision": 0.9, "tp": 9, "fn": 1, "fp": fp, "tn": 5, "false_touches": fp, "touches": 10, "by_label": {}}

    points = round(100 * (pred_recall - 0.9), 2)
    return {
        "scale": 0.1, "seed": 1, "trials": 16, "calibration": {"coverage": 1.0},
        "conditions": {"flat": cond(0.9, 1), "face": cond(1.0, 6), "face_predicted": cond(pred_recall, pred_fp)},
        "verdict": {"fp_trials_not_above_flat": pred_fp <= 1, "false_touches_not_above_flat": pred_fp <= 1,
                    "recall_points_vs_flat": points, "recall_within_2_points": points >= -2.0},
    }


@pytest.mark.parametrize("pred_fp, pred_recall, code", [(1, 0.9, 0), (2, 0.9, 1), (1, 0.8, 1)])
def test_facevideo_bench_prints_the_table_and_fails_when_the_face_fools_the_sensor(tmp_path, capsys, monkeypatch, pred_fp, pred_recall, code):
    import feelium.lab.projector.facevideo as facevideo

    monkeypatch.setattr(facevideo, "run_experiment", lambda **kw: _fake_report(pred_fp, pred_recall))
    report_path = tmp_path / "fv.json"
    assert main(["bench", "projector-facevideo", "--json", str(report_path)]) == code
    out = capsys.readouterr().out
    assert "face_predicted" in out and "false touches" in out
    assert json.loads(report_path.read_text())["conditions"]["face_predicted"]["fp"] == pred_fp
