"""`feelium run --replay` of a face-on recording: touch predicts the light from the recording's own projector stream,
as `feelium replay` does, and says so in health; without the stream it says the light is not compensated."""

from __future__ import annotations

import dataclasses
import shutil

import pytest

from feelium.daemon.assembly import build_touch
from feelium.daemon.config import Config
from feelium.events import TouchEvent
from feelium.hub import Hub
from feelium.lab.sim import conditions, protocol
from feelium.lab.touch import faceon
from feelium.lab.touch.recorded_light import recorded_light
from feelium.lab.touch.replay import replay_recording
from feelium.projector.config import ProjectorConfig
from feelium.recording import CALIBRATION_FILE, Recording
from feelium.touch.config import TouchConfig

from .test_daemon_inprocess import REAR_ONLY, _replay_config, _run_until

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def face_on(tmp_path_factory):
    """A tap and an empty trial with the wearer's face on the skin (`simulate condition faceon`, seed 0), the
    projector stream and its map beside them, as the simulator writes them."""
    root = tmp_path_factory.mktemp("faceon")
    items = [next(i for i in protocol.plan(0.01) if i.label == label and not i.clip) for label in ("tap", "empty")]
    jobs = [conditions.Job("faceon", "face", f"faceon-face/{item.relpath}", item) for item in items]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(faceon, "WARMUP_S", 1.0)  # the experiment's 5 s warm-up, cut to keep the test short
        mp.setattr(conditions, "plan", lambda c, v, s, clips=False: jobs)
        conditions.simulate_condition(root, "faceon", variants=("face",), scale=0.01)
    return root


def _key(event: TouchEvent) -> tuple:
    return (event.phase, event.kind, round(event.x, 2), round(event.y, 2), round(event.depth, 3))


def _lab_events(root, light: bool) -> list[list[TouchEvent]]:
    """`feelium replay`'s events per recording, in the replay camera's order: with the stream's light, or blind."""
    out = []
    for path in sorted(p.parent for p in root.rglob("meta.json")):
        recording = Recording(path)
        feed = recorded_light(recording, root, ProjectorConfig(), TouchConfig()) if light else None
        out.append(replay_recording(recording, TouchConfig(), light=feed).events)
    return out


async def _daemon(root):
    hub = Hub()
    sub = hub.bus.subscribe([TouchEvent])
    config: Config = _replay_config(root)
    await _run_until(config, lambda h, s: s.records["touch"].state == "finished", hub=hub, builders=REAR_ONLY)
    return sub.drain(), hub.health()["services"]["touch"]


def _same_touches(daemon: list[TouchEvent], lab: list[list[TouchEvent]]) -> bool:
    """The same events, recording by recording (the daemon's clock moves each later recording by one shift)."""
    flat = [e for events in lab for e in events]
    if [_key(e) for e in daemon] != [_key(e) for e in flat]:
        return False
    return all(abs((d.t - e.t) - (daemon[0].t - flat[0].t)) < 1e-6 for d, e in zip(daemon, flat))


async def test_a_replayed_face_on_recording_is_compensated_with_its_own_stream_as_replay_does(face_on):
    seen, blind = _lab_events(face_on, light=True), _lab_events(face_on, light=False)
    assert [len(e) for e in seen] == [0, 3]  # empty: no phantom from the face; the tap: down, move, up
    assert not _same_touches([e for events in blind for e in events], seen)  # blind, the tap is read elsewhere
    events, health = await _daemon(face_on)
    assert _same_touches(events, seen)
    assert health["projection_compensation"] is True and health["projector_frames"] > 0
    assert "recorded projector stream" in health["light_source"] and CALIBRATION_FILE in health["light_source"]
    assert health["probe_frames"] == 0  # the live projector's probe never lit these frames


async def test_without_the_stream_the_replay_is_blind_to_the_face_and_health_says_so(face_on, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(face_on, copy)
    for stream in copy.rglob("projector*"):
        if stream.name in ("projector.mkv", "projector_ts.txt"):
            stream.unlink()
    events, health = await _daemon(copy)
    assert _same_touches(events, _lab_events(copy, light=False))  # what replay gives blind ...
    assert not _same_touches(events, _lab_events(face_on, light=True))  # ... not the compensated touches
    assert health["projection_compensation"] is False
    assert health["light_source"] == "replay without a projector stream: the projected light is not compensated"


async def test_a_stream_without_its_map_plays_uncompensated_and_names_the_missing_map(face_on, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(face_on, copy)
    (copy / "faceon-face" / CALIBRATION_FILE).unlink()
    events, health = await _daemon(copy)
    assert health["projection_compensation"] is False and health["projected_errors"] == 2  # one per recording
    assert "NOT compensated" in health["light_source"] and "no projector calibration" in health["light_source"]
    assert _same_touches(events, _lab_events(face_on, light=False))


def test_the_daemon_builds_touch_for_a_replay_without_the_live_projectors_light(face_on):
    """A replayed camera never saw this projector's canvases: touch does not take them, whatever the config says."""
    base = _replay_config(face_on)
    config = dataclasses.replace(base, rear_camera=dataclasses.replace(base.rear_camera, projection_compensation="on"))
    touch = build_touch(config, Hub())
    assert touch.projected is None and touch.stream_light is not None and touch.replayed
    off = dataclasses.replace(base, rear_camera=dataclasses.replace(base.rear_camera, projection_compensation="off"))
    assert build_touch(off, Hub()).stream_light is None
