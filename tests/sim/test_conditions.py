"""``feelium simulate condition`` -> ``feelium eval --by-condition``: each condition's recordings replay to the
events their labels expect, scored under their own condition, with what the recording format allows."""

from __future__ import annotations

import json

import numpy as np
import pytest

from feelium.cli import main
from feelium.lab.sim import conditions, protocol, take_faceon, take_multitouch
from feelium.lab.touch import face_zones, faceon, litroom
from feelium.lab.touch.commands import evaluate_dataset
from feelium.lab.touch.contact_score import gesture_of
from feelium.lab.touch.recorded_light import CALIBRATION_FILE, recorded_light
from feelium.lab.touch.replay import replay_recording
from feelium.projector.config import ProjectorConfig
from feelium.recording import Recording, RecordingError
from feelium.skin.face import FaceModel
from feelium.touch import pipeline as pipeline_module
from feelium.touch.config import TouchConfig
from feelium.touch.reference import AdaptiveReference

pytestmark = pytest.mark.slow


def _first(label: str) -> protocol.Item:
    return next(item for item in protocol.plan(0.01) if item.label == label and not item.clip)


def _litroom_trial(tmp_path, monkeypatch, label: str, variant: str) -> Recording:
    """One protocol trial of ``label`` under ``variant``, written as ``feelium simulate condition litroom`` does."""
    item = _first(label)
    job = conditions.Job("litroom", variant, f"litroom-{variant}/{item.relpath}", item)
    monkeypatch.setattr(conditions, "plan", lambda c, v, s, clips=False: [job])
    (path,) = conditions.simulate_condition(tmp_path, "litroom", variants=(variant,), scale=0.01)
    return Recording(path)


def test_a_tap_through_a_lamp_switched_on_is_one_touch_of_its_condition(tmp_path, monkeypatch):
    recording = _litroom_trial(tmp_path, monkeypatch, "tap", "switch-on")
    generator = recording.meta.raw["generator"]
    assert generator["condition"] == "litroom/switch-on"
    assert generator["room"]["level"] == 0.0 and generator["room"]["steps"][0][1] == 1.0  # the lamp comes on
    assert recording.frames().__next__()[0] < 0.0  # the hand-free warm-up is recorded before 0 s
    assert recording.labels is not None and recording.labels.light_switches == (generator["room"]["steps"][0][0],)
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    trials = report["conditions"]["litroom/switch-on"]["trials"]
    assert (trials["tp"], trials["fp"], trials["fn"]) == (1, 0, 0)
    # a switch with a hand on the membrane: recovery is not read from it (the hand would be read), but counted
    recovery = report["conditions"]["litroom/switch-on"]["switch_recovery"]
    assert (recovery["n"], recovery["not_measurable"], recovery["within_goal"]) == (0, 1, None)


def test_a_hold_through_a_lamp_switched_off_is_scored_with_the_probe_it_was_lit_by(tmp_path, monkeypatch):
    """litroom/switch-off: the static skin with the probe laid on it is the projector stream, the calibration lies
    beside the trial, and eval predicts the light from them as the daemon does. The probe's few percent are all the
    share is learned from (a static skin used to leave it unknown: nothing settled, no touch) and the hold lasts
    through the lamp going off (the share's waver after the switch used to restart the reference under it)."""
    recording = _litroom_trial(tmp_path, monkeypatch, "hold", "switch-off")
    generator = recording.meta.raw["generator"]
    assert recording.has_projector and generator["condition"] == "litroom/switch-off"
    assert generator["probe"]["amplitude"] > 0.0 and generator["room"]["steps"][0][1] == 0.0  # the lamp goes off
    assert (tmp_path / "litroom-switch-off" / CALIBRATION_FILE).is_file()
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    trials = report["conditions"]["litroom/switch-off"]["trials"]
    assert (trials["tp"], trials["fp"], trials["fn"]) == (1, 0, 0)


def test_recovery_after_a_labelled_switch_is_read_from_a_hand_free_recording_and_can_fail(tmp_path, monkeypatch):
    """litroom/switch-off, an empty trial: eval reads the lab's sensitivity measure after the labelled switch, within
    the 1 s goal. With the reference not allowed to follow the switch (no re-seed, no re-baseline, no update after
    it: the lab's own check) the known contact never reads as in steady light again, and the goal fails."""
    recording = _litroom_trial(tmp_path, monkeypatch, "empty", "switch-off")
    assert recording.labels is not None
    (switch,) = recording.labels.light_switches
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    got = report["conditions"]["litroom/switch-off"]
    recovery = got["switch_recovery"]
    assert (recovery["n"], recovery["never"], recovery["not_measurable"]) == (1, 0, 0)
    assert recovery["within_goal"] and recovery["recovery_s"]["max"] <= 1.0
    assert recovery["switch_times_from"] == {"label": 1}
    assert got["light"]["recordings_degraded_by_reason"]["too bright"] == 0

    update = AdaptiveReference.update
    monkeypatch.setattr(pipeline_module, "illumination_change", lambda *a, **k: None)
    monkeypatch.setattr(AdaptiveReference, "observe_gain", lambda self, gain, *a, **k: setattr(self, "gain", gain) or False)
    monkeypatch.setattr(AdaptiveReference, "update", lambda self, t, *a, **k: None if t > switch else update(self, t, *a, **k))
    frozen, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    recovery = frozen["conditions"]["litroom/switch-off"]["switch_recovery"]
    assert (recovery["n"], recovery["never"], recovery["within_goal"]) == (1, 1, False)
    assert recovery["recovery_s"]["max"] is None  # never: no number


def test_a_membrane_too_bright_to_see_is_reported_as_health_would_say_it(tmp_path, monkeypatch, capsys):
    """litroom/too-bright (daylight 8x the projector, the camera's exposure at its floor): health's own judge, fed
    during eval's replay, says "too bright" on the frames and would have reported touch degraded; the table says
    what the detector did beside it."""
    _litroom_trial(tmp_path, monkeypatch, "tap", "too-bright")
    report_path = tmp_path / "report.json"
    assert main(["eval", str(tmp_path), "--by-condition", "--json", str(report_path), "--figure", str(tmp_path / "f.png")]) == 0
    got = json.loads(report_path.read_text())["conditions"]["litroom/too-bright"]
    light = got["light"]
    assert light["present_share"]["too bright"] > 0.5 and light["degraded_share"]["too bright"] > 0.0
    assert light["recordings_degraded"] == 1 and light["recordings_degraded_by_reason"]["too bright"] == 1
    assert got["trials"]["n"] == 1 and got["switch_recovery"] is None  # no switch: no recovery to report
    out = capsys.readouterr().out
    assert "health degraded" in out and "too bright 1" in out


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


def test_a_hover_at_the_rim_is_placed_in_its_zone_by_the_point_it_was_aimed_at(tmp_path):
    """A hover has no contact; its prompted point is its target, so the zones can say whether the rim's hovers fire."""
    trial = next(t for t in face_zones.plan(1) if t.zone == "edge" and t.label == "hover")
    job = conditions.Job("face", "edge", f"face-edge/{trial.session}/{trial.name}", trial, frame=(640, 480))
    path = conditions.write_job(job, tmp_path, seed=1, scale=0.01)
    face = FaceModel.for_frame(640, 480)
    target = Recording(path).labels.target
    assert target is not None and face_zones.zone_of(*face.to_uv(*target)) == "edge"
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    zones = report["zones"]
    assert zones["unplaced"] == 0 and zones["edge"]["fp"] + zones["edge"]["tn"] == 1


def test_a_tap_under_the_face_is_recorded_with_what_was_projected_and_scored_with_it(tmp_path, monkeypatch):
    """faceon/face: the projector stream and the calibration beside the trial; eval predicts the light from them."""
    monkeypatch.setattr(faceon, "WARMUP_S", 1.0)  # the experiment's 5 s warm-up, cut to keep the test short
    item = _first("tap")
    monkeypatch.setattr(conditions, "plan", lambda c, v, s, clips=False: [conditions.Job("faceon", "face", f"faceon-face/{item.relpath}", item)])
    (path,) = conditions.simulate_condition(tmp_path, "faceon", variants=("face",), scale=0.01)
    recording = Recording(path)
    assert recording.has_projector and recording.meta.raw["generator"]["condition"] == "faceon/face"
    shown = [t for t, _ in recording.projector_frames()]
    assert shown[0] < recording.timestamps[0] and shown[-1] >= recording.timestamps[-1]  # covers every exposure
    assert (tmp_path / "faceon-face" / CALIBRATION_FILE).is_file()
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    trials = report["conditions"]["faceon/face"]["trials"]
    assert (trials["tp"], trials["fp"], trials["fn"]) == (1, 0, 0)
    # The stream is used: the same frames replayed blind to the face give other gate scores.
    light = recorded_light(recording, tmp_path, ProjectorConfig(), TouchConfig())
    assert light is not None
    seen, blind = replay_recording(recording, TouchConfig(), light=light), replay_recording(recording, TouchConfig())
    assert not np.allclose(seen.core_depth, blind.core_depth)
    (tmp_path / "faceon-face" / CALIBRATION_FILE).unlink()
    with pytest.raises(RecordingError, match="no labelled recording"):  # skipped as bad, named on stderr
        evaluate_dataset(tmp_path, TouchConfig())


def test_a_tap_under_the_face_in_a_lit_room_is_its_own_condition_scored_with_its_margins(tmp_path, monkeypatch):
    """faceon/face-lit: the lit-room experiment's lamp in the recording's meta, the stream and the map beside the
    trial; eval scores it under its own condition, with every gate's margins."""
    monkeypatch.setattr(faceon, "WARMUP_S", 1.0)
    item = _first("tap")
    monkeypatch.setattr(conditions, "plan", lambda c, v, s, clips=False: [conditions.Job("faceon", "face-lit", f"faceon-face-lit/{item.relpath}", item)])
    (path,) = conditions.simulate_condition(tmp_path, "faceon", variants=("face-lit",), scale=0.01)
    recording = Recording(path)
    generator = recording.meta.raw["generator"]
    assert recording.has_projector and generator["condition"] == "faceon/face-lit"
    assert generator["room"]["level"] == litroom.LIT and not generator["room"]["steps"]  # steady lamp
    assert (tmp_path / "faceon-face-lit" / CALIBRATION_FILE).is_file()
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    lit = report["conditions"]["faceon/face-lit"]
    assert (lit["trials"]["tp"], lit["trials"]["fp"], lit["trials"]["fn"]) == (1, 0, 0)
    assert {"edge", "instant", "sustained"} <= set(lit["margins"]["trials"])


def test_two_hands_and_a_palm_are_labelled_contact_by_contact_and_eval_scores_each(tmp_path):
    run = take_multitouch.runs("palm-and-finger", 0.1)[0]
    job = conditions.Job("multitouch", "palm-and-finger", f"multitouch-palm-and-finger/{run.session}/{run.name}", run)
    path = conditions.write_job(job, tmp_path, seed=1, scale=0.1)
    labels = Recording(path).labels
    assert labels is not None and [c.contact for c in labels.contacts] == ["palm", "finger"]
    # the trial's label is the gesture of its longest contact (the palm, 1.6 s: a hold), each contact's its own
    assert labels.label == "hold" and [gesture_of(c) for c in labels.contacts] == ["hold", "hold"]
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    got = report["conditions"]["multitouch/palm-and-finger"]["contacts"]
    assert (got["gesture_right"], got["gesture_scored"]) == (2, 2)
    assert (got["contacts"], got["touches"], got["missed"], got["split"], got["swaps"], got["phantoms"]) == (2, 2, 0, 0, 0, 0)
    assert got["kinds"] == {"finger": {"finger": 1, "palm": 0, "hug": 0, "none": 0}, "palm": {"finger": 0, "palm": 1, "hug": 0, "none": 0}}


def test_the_cli_writes_one_folder_per_variant_and_eval_reports_each(tmp_path, capsys, monkeypatch):
    """The command-line path; the plan cut to one empty trial per variant asked for, to keep the test short."""
    whole = conditions.plan

    def one_each(condition, variants, scale, clips=False):
        jobs = [job for job in whole(condition, variants, scale, clips) if job.trial.label == "empty"]
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
    with pytest.raises(ValueError, match="unknown variant"):
        conditions.plan("multitouch", ("three-hands",), 0.1)


def test_the_multitouch_plan_runs_every_scene_round_robin_over_the_sessions():
    jobs = conditions.plan("multitouch", ("hug", "swipe-cross"), 0.5)
    assert [j.relpath for j in jobs] == [
        "multitouch-hug/s1/hug-s1-001", "multitouch-hug/s2/hug-s2-001", "multitouch-hug/s3/hug-s3-001",
        "multitouch-swipe-cross/s1/swipe-cross-s1-001", "multitouch-swipe-cross/s2/swipe-cross-s2-001",
        "multitouch-swipe-cross/s3/swipe-cross-s3-001",
    ]  # fmt: skip
    assert len(conditions.plan("faceon", ("static", "face"), 0.05)) == 2 * 13
    assert len(conditions.plan("faceon", take_faceon.VARIANTS, 0.05)) == 4 * 13  # each also in the lit room


def test_the_paper_gates_alone_are_scored_beside_the_pipeline_on_the_same_frames(tmp_path, monkeypatch, capsys):
    """faceon/face, a hover: the project's pipeline (contact edge, light predicted from the recorded stream) stays
    silent; the paper's two gates, blind to the face, are reported beside it on the same frames."""
    monkeypatch.setattr(faceon, "WARMUP_S", 1.0)
    item = _first("hover")
    monkeypatch.setattr(conditions, "plan", lambda c, v, s, clips=False: [conditions.Job("faceon", "face", f"faceon-face/{item.relpath}", item)])
    conditions.simulate_condition(tmp_path, "faceon", variants=("face",), scale=0.01)
    report_path = tmp_path / "report.json"
    assert main(["eval", str(tmp_path), "--by-condition", "--paper-gates", "--json", str(report_path),
                 "--figure", str(tmp_path / "f.png")]) == 0  # fmt: skip
    report = json.loads(report_path.read_text())
    ours, paper = report["conditions"]["faceon/face"], report["conditions"]["faceon/face"]["paper_gates"]
    assert ours["trials"]["n"] == paper["trials"]["n"] == 1
    assert ours["trials"]["fp"] == 0
    assert paper["margins"]["trials"]["edge"]["threshold"] == 0.0  # no contact edge: only the two gates decide
    hardest = [r["margins"]["trials"]["sustained"]["hardest_negative"] for r in (ours, paper)]
    assert hardest[0] != hardest[1]  # replayed blind to the face: another pipeline's scores, not a copy of ours
    assert report["paper_gates"]["trials"]["n"] == 1 and "conditions" not in report["paper_gates"]
    printed = capsys.readouterr().out
    assert "the paper's two gates alone" in printed and "faceon/face" in printed.split("the paper's two gates alone")[1]


def test_face_on_clips_are_fitted_with_the_light_predicted_from_their_stream(tmp_path, monkeypatch):
    """`simulate condition faceon --clips` writes continuous clips with their projector stream; `calibrate touch` fits
    the gates on them as the daemon sees them, the face's light predicted, never blind."""
    from feelium.lab.touch import commands
    from feelium.lab.touch.skips import Skips

    monkeypatch.setattr(faceon, "WARMUP_S", 1.0)
    whole = conditions.plan
    monkeypatch.setattr(conditions, "plan", lambda c, v, s, clips=False: [
        j for j in whole(c, v, s, clips) if j.trial.clip and j.trial.label in ("contact", "hover")])  # fmt: skip
    written = conditions.simulate_condition(tmp_path, "faceon", variants=("face",), scale=0.01, clips=True)
    assert [Recording(p).labels.label for p in written] == ["contact", "hover"]
    fed = []
    real = commands.recorded_light

    def counted(recording, root, projector, touch, calibration=None):
        light = real(recording, root, projector, touch, calibration)
        fed.append(light is not None)
        return light

    monkeypatch.setattr(commands, "recorded_light", counted)
    fit = commands.fit_on_clips([Recording(p) for p in written], TouchConfig(), Skips("test"), root=tmp_path)
    assert fed == [True] * 4  # both clips, in both passes (the edge, then the depth gates with the fitted edge)
    assert 0 < fit.values()["contact_edge"] and 0 < fit.values()["instant_depth"] < 1
    with pytest.raises(ValueError, match="only litroom and faceon"):
        conditions.simulate_condition(tmp_path / "x", "multitouch", scale=0.01, clips=True)
