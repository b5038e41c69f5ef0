"""`feelium record --projector`: the take keeps what lit the membrane (the projector stream, on the camera's clock,
from before the first exposure) and the calibration its replay needs."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.cameras.base import Frame
from feelium.cameras.record import PROJECTOR_LEAD, record
from feelium.cli import main
from feelium.projector.config import ProjectorConfig
from feelium.projector.display import SimDisplay
from feelium.projector.renderer import Renderer
from feelium.projector.showloop import ShowLoop
from feelium.recording import Recording
from feelium.skin.projector_map import DEFAULT_CAMERA_SIZE, DEFAULT_ROI, default_calibration


class ProjectingCamera:
    """A camera whose every read first lets a scripted projector show a frame (the two clocks are one)."""

    name = "scripted"
    realtime = True

    def __init__(self, times, shows):
        self.times, self.shows = list(times), shows

    def read(self):
        if not self.times:
            return None
        t = self.times.pop(0)
        self.shows.show(t - 0.01)
        return Frame(t=t, image=np.full((6, 8), 100, np.uint8), roi=None)

    def close(self):
        pass


class ScriptedProjector:
    """A projector stream driven by the camera's reads; ``before`` frames shown before the first exposure."""

    size = (16, 8)
    fps = 30.0
    error = None

    def __init__(self, before):
        self.before, self.sink, self.stopped = before, None, False

    def start(self, sink):
        self.sink = sink
        for t in self.before:
            self.show(t)

    def show(self, t):
        self.sink(t, np.full((8, 16, 3), int(t * 100) % 256, np.uint8))

    def stop(self):
        self.stopped = True


def test_the_projector_stream_is_kept_on_the_cameras_time_axis_from_before_the_first_exposure(tmp_path):
    projector = ScriptedProjector(before=[9.80, 9.85, 9.90, 9.93, 9.96])
    camera = ProjectingCamera([10.0, 10.1, 10.2], projector)
    take = record(camera, tmp_path / "r", seconds=None, fps=10.0, name="r", projector=projector,
                  files={"projector-calibration.npz": b"map"})  # fmt: skip
    rec = Recording(take.path)
    assert rec.has_projector and projector.stopped
    shown = [t for t, _ in rec.projector_frames()]
    # held until the time origin exists (the camera thread may read ahead): the last PROJECTOR_LEAD shown up to the
    # first exposure, then every later one
    expected = [t - 10.0 for t in [9.80, 9.85, 9.90, 9.93, 9.96, 9.99][-PROJECTOR_LEAD:]] + [0.09, 0.19]
    assert shown == pytest.approx(expected, abs=1e-6)
    assert take.projector_frames == len(expected) and take.projector_problem == ""
    assert (take.path / "projector-calibration.npz").read_bytes() == b"map"


def test_a_file_that_would_overwrite_the_formats_own_is_refused(tmp_path):
    projector = ScriptedProjector(before=[])
    with pytest.raises(ValueError, match="not a plain file name"):
        record(ProjectingCamera([0.0], projector), tmp_path / "r", seconds=None, fps=10.0, name="r", projector=projector,
               files={"meta.json": b"{}"})  # fmt: skip
    assert list(tmp_path.iterdir()) == []  # nothing half left


def _show_loop(content, **kw):
    config = ProjectorConfig()
    size = (config.width, config.height)
    renderer = Renderer(config, default_calibration(DEFAULT_CAMERA_SIZE, DEFAULT_ROI, size))
    return ShowLoop(renderer, SimDisplay(), fps=config.fps, content=content, **kw)


def test_the_show_loop_renders_the_talking_avatar_and_a_flat_back_light():
    loop = _show_loop("avatar")
    frames = [loop.frame_at(t).copy() for t in (0.0, 0.5, 1.0, 1.5)]
    assert frames[0].shape == (loop.size[1], loop.size[0], 3)
    assert any(not np.array_equal(frames[0], f) for f in frames[1:])  # it moves: a face, not a still
    flat = _show_loop("flat").frame_at(3.0)
    assert flat.min() == flat.max() == 255
    with pytest.raises(ValueError, match="face video"):
        _show_loop("face")


def test_the_show_loop_plays_a_face_video_looped(tmp_path):
    import cv2

    video = tmp_path / "face.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    for level in (40, 120, 200):
        writer.write(np.full((48, 64, 3), level, np.uint8))
    writer.release()
    loop = _show_loop("face", face_video=video)
    levels = [int(loop._video.at(t).mean()) for t in (0.0, 0.1, 0.2, 0.3, 0.4)]  # noqa: SLF001
    assert levels[0] == levels[3] and levels[1] == levels[4] and len({levels[0], levels[1], levels[2]}) == 3


@pytest.mark.slow
def test_record_with_the_avatar_keeps_a_replayable_take(tmp_path, monkeypatch):
    """End to end: the avatar shown on its thread, the stream covering every exposure, the calibration in the take,
    and replay finds it there; kept only from the device camera, which sees the projector."""
    config_file = tmp_path / "feelium.toml"
    config = ProjectorConfig()
    default_calibration(DEFAULT_CAMERA_SIZE, DEFAULT_ROI, (config.width, config.height)).save(tmp_path / "projector_calibration.npz")
    config_file.write_text('[projector]\nbackend = "sim"\n', encoding="utf-8")
    out = tmp_path / "take"
    sim_take = tmp_path / "sim-take"
    assert main(["record", "--sim", "--config", str(config_file), "--out", str(sim_take), "--seconds", "0.5", "--projector", "avatar"]) == 0
    assert not Recording(sim_take).has_projector  # the simulated camera does not see the projector: no stream kept
    from feelium.cameras import select
    from feelium.daemon import assembly

    real = assembly.rear_camera

    def device(config, clock):  # the simulated frames, as if from the blimp's camera, which does see the projector
        return select.CameraSource("picamera2", real(config, clock).open)

    monkeypatch.setattr(assembly, "rear_camera", device)
    assert main(["record", "--config", str(config_file), "--out", str(out), "--seconds", "1", "--projector", "avatar"]) == 0
    rec = Recording(out)
    shown = [t for t, _ in rec.projector_frames()]
    assert shown[0] <= rec.timestamps[0] and shown[-1] >= rec.timestamps[-1] - 0.1
    assert np.all(np.diff(shown) > 0) and len(shown) >= 20
    from feelium.lab.touch.recorded_light import find_calibration

    assert find_calibration(out, out) == (out / "projector-calibration.npz").resolve()
    assert main(["record", "--sim", "--out", str(tmp_path / "t2"), "--seconds", "1", "--face-video", "x.mp4"]) == 2
    assert main(["record", "--sim", "--config", str(config_file), "--out", str(tmp_path / "t3"), "--seconds", "1",
                 "--projector", "face", "--face-video", str(tmp_path / "missing.mp4")]) == 1  # fmt: skip
    assert not (tmp_path / "t3").exists()
