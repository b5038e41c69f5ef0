"""End to end: simulate a small paper-protocol dataset, then replay, calibrate, evaluate and bench it.

The dataset is tiny (scale 0.05: 13 trials and three 6 s clips) so the whole
module stays within a few tens of seconds; scores are asserted at levels a
broken stage would miss by far, not tuned to this seed.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import replace

import pytest

from feelium.cli import main
from feelium.daemon.config import load_config
from feelium.lab.sim.protocol import simulate_protocol
from feelium.lab.touch.bench import build_variants, run_variants, summarise

pytestmark = pytest.mark.slow

REPORT_KEYS = {"version", "dataset", "trials", "activity", "area_baseline", "sustained", "localisation", "latency_ms", "speed"}
TRIAL_KEYS = {
    "n", "tp", "fp", "fn", "tn", "precision", "recall", "f1", "by_label", "kind_accuracy", "kind_confusion",
    "single_event_rate",
}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("touch-e2e")
    simulate_protocol(root, seed=7, scale=0.05, jobs=2, thermal=False)
    return root


def test_eval_report_follows_the_spec_and_scores_well(dataset, tmp_path, capsys):
    report_path = tmp_path / "report.json"
    figure = tmp_path / "anchoring.png"
    assert main(["eval", str(dataset), "--json", str(report_path), "--figure", str(figure)]) == 0
    report = json.loads(report_path.read_text())
    assert set(report) >= REPORT_KEYS and report["version"] == 1
    assert set(report["trials"]) >= TRIAL_KEYS
    trials = report["trials"]
    assert trials["n"] == 13
    assert trials["recall"] >= 0.85
    assert trials["precision"] >= 0.85
    assert report["trials"]["by_label"]["empty"]["fired"] == 0
    assert report["activity"]["empty_fired"] == 0
    assert trials["kind_accuracy"] >= 0.85
    assert report["localisation"]["error_px"]["median"] <= 3.0
    assert report["latency_ms"]["median"] <= 250.0
    # A hover's shadow has no contact edge (score 0) and a press scores its depth from the frame it lands,
    # so even on 6 s clips, where each press's onset weighs a lot, contact ranks above hover.
    assert report["sustained"]["auc"] is not None and report["sustained"]["auc"] >= 0.95
    assert report["sustained"]["balanced_accuracy_holdout"] >= 0.9
    assert figure.stat().st_size > 1000
    # Added keys (issue 17 point 5): each gate's hardest cases against the threshold in use.
    margins = report["margins"]
    config = load_config(None).touch
    for sample in ("trials", "clips"):
        edge, instant, sustained = (margins[sample][gate] for gate in ("edge", "instant", "sustained"))
        assert (edge["threshold"], instant["threshold"], sustained["threshold"]) == (
            config.contact_edge, config.instant_depth, config.anchor_threshold
        )
        for m in (edge, instant, sustained):
            assert m["negative_margin"] == pytest.approx(m["threshold"] - m["hardest_negative"])
            assert m["positive_margin"] == pytest.approx(m["hardest_positive"] - m["threshold"])
    assert margins["trials"]["instant"]["negatives"] == sum(
        e["n"] for label, e in trials["by_label"].items() if label in ("hover", "disturbance", "empty")
    )
    out = capsys.readouterr().out
    assert "precision / recall / F1" in out
    assert "margins trials, instant" in out


def test_calibrate_writes_a_fragment_that_eval_accepts(dataset, tmp_path, capsys):
    fragment = tmp_path / "touch.toml"
    assert main(["calibrate", "touch", str(dataset), "--out", str(fragment)]) == 0
    config = load_config(str(fragment)).touch
    assert 0.0 < config.anchor_threshold < 1.0
    assert config.anchor_threshold <= config.instant_depth <= 0.99
    assert 0.0 < config.contact_edge < 0.5  # depth per camera px: between a hover's soft edge and a press's
    assert main(["eval", str(dataset), "--fit-on-clips", "--json", str(tmp_path / "fit.json")]) == 0
    fit_report = json.loads((tmp_path / "fit.json").read_text())
    assert fit_report["trials"]["recall"] >= 0.85
    fitted = fit_report["touch_config"]
    assert fitted["fitted_on_clips"] is True
    assert fitted["anchor_threshold"] == pytest.approx(config.anchor_threshold, abs=1e-4)
    assert fitted["contact_edge"] == pytest.approx(config.contact_edge, abs=1e-4)
    # Clips under the flat back-light (no projector stream) teach the projected-light gate nothing: kept, and said.
    assert "contact_projected_depth = " not in fragment.read_text() and config.contact_projected_depth == 0.2
    assert "# contact_projected_depth 0.2 kept as configured" in fragment.read_text()
    assert fitted["contact_projected_depth"] == 0.2 and "kept as configured" in fitted["fit_notes"][0]


def test_replay_prints_events_with_the_recording_name(dataset, capsys):
    assert main(["replay", str(dataset / "s1")]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert lines, "a dataset with taps must replay into events"
    assert {"id", "phase", "kind", "t", "x", "y", "u", "v", "depth", "area", "anchor", "recording"} <= set(lines[0])
    assert all(line["recording"].startswith("s1-") for line in lines)
    assert {line["phase"] for line in lines} >= {"down", "up"}


def test_bench_compares_every_resolution_with_the_plain_baseline(dataset):
    config = replace(load_config(None).touch)
    variants = build_variants(config)
    run_variants(dataset / "s1", variants)
    report = summarise(dataset / "s1", variants, (640, 480))
    rows = report["variants"]
    assert [r["plain"] for r in rows] == [True, False, False, False]
    assert [(r["width"], r["height"]) for r in rows] == [(640, 480), (640, 480), (320, 240), (160, 120)]
    assert rows[0]["speedup_vs_plain"] == pytest.approx(1.0)
    assert all(r["frames"] == rows[0]["frames"] > 0 for r in rows)
    assert all(r["cpu_ms_per_frame"]["median"] > 0 for r in rows)
    # The plain baseline is the same algorithm: at full resolution it must score like the fast path.
    assert rows[0]["f1"] == pytest.approx(rows[1]["f1"], abs=0.15)
    json.dumps(report)  # the report is plain JSON


def test_bench_by_condition_splits_the_same_frames_and_scores_by_the_datasets_folders(dataset, tmp_path, capsys):
    tiny = tmp_path / "tiny"
    for condition, name in (("lit", "s1/s1-tap-001"), ("dim", "s1/s1-hover-001")):
        shutil.copytree(dataset / name, tiny / condition / name.split("/")[1], copy_function=os.link)
    out = tmp_path / "bench.json"
    assert main(["bench", "touch", "--dataset", str(tiny), "--by-condition", "--json", str(out)]) == 0
    assert "condition dim:" in capsys.readouterr().out
    report = json.loads(out.read_text())
    conditions = report["conditions"]
    assert sorted(conditions) == ["dim", "lit"]
    for whole, *parts in zip(report["variants"], conditions["dim"]["variants"], conditions["lit"]["variants"]):
        assert whole["frames"] == sum(p["frames"] for p in parts) > 0  # every frame in exactly one condition
        median = whole["cpu_ms_per_frame"]["median"]
        assert whole["light_cpu_ms_per_frame"]["median"] == 0.0  # no projector stream: nothing predicted
        assert whole["pi_fps_at_10x"] == pytest.approx(100.0 / median, abs=0.05)
    dim = conditions["dim"]["variants"][2]  # the daemon's 320x240
    lit = conditions["lit"]["variants"][2]
    assert lit["recall"] == 1.0  # the tap, found
    assert dim["recall"] is None and dim["precision"] is None  # the hover alone: nothing to find, nothing found
