"""The whole face with the face projected or the room lit (``simulate condition face --variants edge-faceon,...``)."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.lab.sim import conditions, take_wholeface
from feelium.lab.touch import face_zones, faceon, litroom
from feelium.lab.touch.commands import evaluate_dataset
from feelium.lab.touch.recorded_light import CALIBRATION_FILE, recorded_light
from feelium.lab.touch.replay import replay_recording
from feelium.projector.config import ProjectorConfig
from feelium.recording import Recording
from feelium.sim.projection import FisheyeWarp
from feelium.skin.face import FaceModel
from feelium.skin.projector_map import load_calibration
from feelium.touch.config import TouchConfig

FRAME = (640, 480)  # the face bench's lens on a smaller frame: the same paths in a quarter of the pixels


def _edge_trial(tmp_path, monkeypatch, label: str, variant: str) -> Recording:
    """One trial of ``label`` at the rim, written as ``feelium simulate condition face --variants VARIANT`` does."""
    trial = next(t for t in face_zones.plan(1) if t.zone == "edge" and t.label == label)
    job = conditions.Job("face", variant, f"face-{variant}/{trial.session}/{trial.name}", trial, frame=FRAME)
    monkeypatch.setattr(conditions, "plan", lambda c, v, s, clips=False: [job])
    (path,) = conditions.simulate_condition(tmp_path, "face", variants=(variant,), scale=0.01)
    return Recording(path)


def _the_map_beside_covers_the_face(tmp_path, variant: str) -> None:
    """The map beside the trials is the face frame's own and covers the whole face, rim included: the rectangle's
    (640x480 over the paper's patch) would leave the rim unpredicted."""
    cal = load_calibration(tmp_path / f"face-{variant}" / CALIBRATION_FILE)
    face = FaceModel.for_frame(*FRAME)
    assert cal.camera_size == FRAME and tuple(cal.roi) == face.roi()
    assert cal.covered[face.mask()].mean() > 0.999


def test_a_tap_at_the_rim_under_the_projected_face_is_recorded_with_the_stream_and_the_faces_map(tmp_path, monkeypatch):
    monkeypatch.setattr(faceon, "WARMUP_S", 1.0)  # the experiment's 5 s warm-up, cut to keep the test short
    recording = _edge_trial(tmp_path, monkeypatch, "tap", "edge-faceon")
    generator = recording.meta.raw["generator"]
    assert recording.has_projector and generator["condition"] == "face/edge-faceon" and generator["light"] == "faceon"
    assert generator["room"] is None and FaceModel.from_json(recording.meta.raw["face"]) == FaceModel.for_frame(*FRAME)
    _the_map_beside_covers_the_face(tmp_path, "edge-faceon")
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    trials = report["conditions"]["face/edge-faceon"]["trials"]
    assert (trials["tp"], trials["fp"], trials["fn"]) == (1, 0, 0)
    assert report["zones"]["edge"]["tp"] == 1
    # The stream is used: the same frames replayed blind to the face give other gate scores.
    light = recorded_light(recording, tmp_path, ProjectorConfig(), TouchConfig())
    assert light is not None
    seen, blind = replay_recording(recording, TouchConfig(), light=light), replay_recording(recording, TouchConfig())
    assert not np.allclose(seen.core_depth, blind.core_depth)


def test_a_hover_at_the_rim_in_the_lit_room_carries_the_lamp_and_the_probe_and_stays_silent(tmp_path, monkeypatch):
    monkeypatch.setattr(litroom, "WARMUP_S", 1.0)
    recording = _edge_trial(tmp_path, monkeypatch, "hover", "edge-lit")
    generator = recording.meta.raw["generator"]
    assert recording.has_projector and generator["condition"] == "face/edge-lit"
    assert generator["room"]["level"] == litroom.LIT and not generator["room"]["steps"]  # the steady lamp
    assert generator["probe"]["amplitude"] > 0.0 and next(recording.frames())[0] < 0.0  # warm-up before 0 s
    _the_map_beside_covers_the_face(tmp_path, "edge-lit")
    report, _ = evaluate_dataset(tmp_path, TouchConfig(), by_condition=True)
    zones = report["zones"]
    assert zones["unplaced"] == 0 and (zones["edge"]["fp"], zones["edge"]["tn"]) == (0, 1)


def test_the_lights_are_variants_per_zone_and_only_they_carry_a_projector_stream():
    assert take_wholeface.variant_light("edge-faceon-lit") == ("edge", "faceon-lit")
    assert take_wholeface.variant_light("mid") == ("mid", None)
    jobs = conditions.plan("face", ("centre", "edge-lit"), 0.1)
    assert {(j.variant, j.trial.zone) for j in jobs} == {("centre", "centre"), ("edge-lit", "edge")}
    assert {j.relpath.split("/")[0] for j in jobs} == {"face-centre", "face-edge-lit"}
    assert [conditions.carries_projector("face", v) for v in ("edge", "edge-faceon", "mid-lit")] == [False, True, True]
    assert conditions.DEFAULT_VARIANTS["face"] == face_zones.ZONES  # the lights only on request
    with pytest.raises(ValueError, match="unknown variant"):
        conditions.plan("face", ("edge-dim",), 0.1)


def test_the_warp_scaled_to_a_finer_camera_sees_the_same_projector_point():
    warp = FisheyeWarp()
    x, y = np.array([30.0, 320.0, 610.0]), np.array([10.0, 240.0, 470.0])
    assert np.allclose(warp.scaled(2.0).camera_to_projector(2 * x, 2 * y), warp.camera_to_projector(x, y))
