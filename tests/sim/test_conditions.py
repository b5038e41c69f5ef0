"""``feelium simulate condition`` -> ``feelium eval --by-condition``: each condition's recordings replay to the
events their labels expect, scored under their own condition, with what the recording format allows."""

from __future__ import annotations

import json

import pytest

from feelium.cli import main
from feelium.lab.sim import conditions, protocol
from feelium.lab.touch import face_zones
from feelium.lab.touch.commands import evaluate_dataset
from feelium.recording import Recording
from feelium.skin.face import FaceModel
from feelium.touch.config import TouchConfig

pytestmark = pytest.mark.slow


def _first(label: str) -> protocol.Item:
    return next(item for item in protocol.plan(0.01) if item.label == label and not item.clip)


def test_a_tap_through_a_lamp_switched_on_is_one_touch_of_its_condition(tmp_path):
    item = _first("tap")
    job = conditions.Job("litroom", "switch-on", f"litroom-switch-on/{item.relpath}", item)
    path = conditions.write_job(job, tmp_path, seed=1, scale=0.01)
    meta = Recording(path).meta.raw
    generator = meta["generator"]
    assert generator["condition"] == "litroom/switch-on"
    assert generator["room"]["level"] == 0.0 and generator["room"]["steps"][0][1] == 1.0  # the lamp comes on
    assert Recording(path).frames().__next__()[0] < 0.0  # the hand-free warm-up is recorded before 0 s
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    trials = report["conditions"]["litroom/switch-on"]["trials"]
    assert (trials["tp"], trials["fp"], trials["fn"]) == (1, 0, 0)


def test_a_tap_at_the_rim_of_the_whole_face_is_one_touch_on_the_face(tmp_path):
    trial = next(t for t in face_zones.plan(1) if t.zone == "edge" and t.label == "tap")
    job = conditions.Job("face", "edge", f"face-edge/{trial.session}/{trial.name}", trial, frame=(640, 480))
    path = conditions.write_job(job, tmp_path, seed=1, scale=0.01)
    meta = Recording(path).meta.raw
    assert FaceModel.from_json(meta["face"]) == FaceModel.for_frame(640, 480)  # the optional meta.face
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    trials = report["conditions"]["face/edge"]["trials"]
    assert (trials["tp"], trials["fp"], trials["fn"]) == (1, 0, 0)
    assert report["localisation"]["error_px"]["median"] < 3.0


def test_the_cli_writes_one_folder_per_variant_and_eval_reports_each(tmp_path, capsys, monkeypatch):
    """The command-line path; the plan cut to one empty trial per variant asked for, to keep the test short."""
    whole = conditions.plan

    def one_each(condition, variants, scale):
        jobs = [job for job in whole(condition, variants, scale) if job.trial.label == "empty"]
        return [next(job for job in jobs if job.variant == v) for v in variants]

    monkeypatch.setattr(conditions, "plan", one_each)
    out = tmp_path / "ds"
    assert main(["simulate", "condition", "litroom", "--out", str(out), "--variants", "dim,passer-by", "--scale", "0.01",
                 "--jobs", "1", "--quiet"]) == 0  # fmt: skip
    assert sorted(p.name for p in out.iterdir()) == ["litroom-dim", "litroom-passer-by"]
    report_path = tmp_path / "report.json"
    assert main(["eval", str(out), "--by-condition", "--json", str(report_path), "--figure", str(tmp_path / "f.png")]) == 0
    report = json.loads(report_path.read_text())
    assert list(report["conditions"]) == ["litroom/dim", "litroom/passer-by"]
    assert [c["trials"]["n"] for c in report["conditions"].values()] == [1, 1] and report["trials"]["n"] == 2
    assert report["trials"]["fp"] == 0
    assert "== condition litroom/passer-by" in capsys.readouterr().out
    assert main(["simulate", "condition", "litroom", "--out", str(out), "--variants", "sunset"]) == 2


def test_unknown_conditions_and_variants_are_named():
    with pytest.raises(ValueError, match="unknown variant"):
        conditions.plan("litroom", ("sunset",), 0.1)
    with pytest.raises(ValueError, match="unknown condition"):
        conditions.plan("underwater", (), 0.1)
