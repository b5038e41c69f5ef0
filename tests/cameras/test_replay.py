"""Replay of format-v1 recordings as a camera: frames, timestamps, segments, loops and pacing."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.cameras.replay import ReplayCamera
from feelium.recording import RecordingError, RecordingWriter


def _write(path, times, value=100, roi=(1, 1, 6, 4)):
    with RecordingWriter(path, name=path.name, width=8, height=6, fps=10.0, roi=roi) as writer:
        for i, t in enumerate(times):
            writer.add_frame(t, np.full((6, 8), value + i, np.uint8))
    return path


def _drain(camera):
    frames = []
    while (frame := camera.read()) is not None:
        frames.append(frame)
    return frames


def test_replays_every_frame_with_its_own_timestamp_and_roi(tmp_path):
    _write(tmp_path / "a", [0.0, 0.1, 0.25, 0.3])
    frames = _drain(ReplayCamera(tmp_path / "a", realtime=False))
    assert [f.t for f in frames] == pytest.approx([0.0, 0.1, 0.25, 0.3])
    assert [int(f.image[0, 0]) for f in frames] == [100, 101, 102, 103]
    assert all(f.image.shape == (6, 8) and f.roi == (1, 1, 6, 4) for f in frames)


def test_a_dataset_plays_recordings_in_order_as_new_segments_with_times_still_increasing(tmp_path):
    _write(tmp_path / "set" / "r1", [0.0, 0.1, 0.2], value=10)
    _write(tmp_path / "set" / "r2", [5.0, 5.1], value=50)
    frames = _drain(ReplayCamera(tmp_path / "set", realtime=False))
    assert [f.segment for f in frames] == [0, 0, 0, 1, 1]
    assert [int(f.image[0, 0]) for f in frames] == [10, 11, 12, 50, 51]
    assert np.all(np.diff([f.t for f in frames]) > 0)
    assert frames[3].t == pytest.approx(0.3)  # the next recording follows one frame period after the last


def test_loop_starts_again_with_increasing_time(tmp_path):
    _write(tmp_path / "a", [0.0, 0.1])
    camera = ReplayCamera(tmp_path / "a", realtime=False, loop=True)
    frames = [camera.read() for _ in range(6)]
    assert [f.segment for f in frames] == [0, 0, 1, 1, 2, 2]
    assert np.all(np.diff([f.t for f in frames]) > 0)
    camera.close()
    assert camera.read() is None


def test_realtime_replay_sleeps_to_the_recordings_pace(tmp_path):
    _write(tmp_path / "a", [0.0, 0.1, 0.4])
    now = [50.0]
    sleeps = []

    def sleep(seconds):
        sleeps.append(seconds)
        now[0] += seconds

    camera = ReplayCamera(tmp_path / "a", realtime=True, clock=lambda: now[0], sleep=sleep)
    frames = _drain(camera)
    assert sleeps == pytest.approx([0.1, 0.3])
    assert [f.t for f in frames] == pytest.approx([50.0, 50.1, 50.4])  # on the given (daemon) clock


def test_missing_path_and_bad_recordings_are_named(tmp_path):
    with pytest.raises(ValueError, match="replay_path"):
        ReplayCamera("")
    with pytest.raises(RecordingError, match="no such file"):
        ReplayCamera(tmp_path / "absent")


def test_a_bad_recording_in_a_dataset_is_skipped_and_named_and_the_good_ones_play(tmp_path, caplog):
    _write(tmp_path / "a", [0.0, 0.1, 0.2])
    bad = _write(tmp_path / "b", [0.0, 0.1, 0.2])
    (bad / "camera_ts.txt").write_text("0.0\n0.1\n0.1\n")  # a time that repeats: fails validation
    _write(tmp_path / "c", [5.0, 5.1])
    with caplog.at_level("WARNING", logger="feelium.cameras.replay"):
        camera = ReplayCamera(tmp_path, realtime=False)
    frames = _drain(camera)
    assert [f.segment for f in frames] == [0, 0, 0, 1, 1]
    assert len(camera.skipped) == 1 and camera.skipped[0].path.is_relative_to(bad)
    assert [r.message for r in caplog.records].count(f"replay: skipped {camera.skipped[0]}") == 1


def test_a_video_that_ends_early_plays_what_it_holds_then_is_left_out_of_the_loop(tmp_path, caplog):
    short = _write(tmp_path / "a", [0.0, 0.1, 0.2, 0.3])
    # The video of "a" is swapped for a two-frame one while its timestamps still promise four.
    spare = _write(tmp_path.parent / f"{tmp_path.name}-spare", [0.0, 0.1])
    (short / "camera.mkv").write_bytes((spare / "camera.mkv").read_bytes())
    _write(tmp_path / "b", [1.0, 1.1])
    camera = ReplayCamera(tmp_path, realtime=False, loop=True)
    with caplog.at_level("WARNING", logger="feelium.cameras.replay"):
        frames = [camera.read() for _ in range(8)]
    assert all(f is not None for f in frames)
    segments = [f.segment for f in frames]
    assert segments[:2] == [0, 0] and 1 in segments  # a's two frames, then b, then b again on each loop
    assert len(camera.skipped) == 1 and camera.skipped[0].path.is_relative_to(short)
    assert len(camera.recordings) == 1


def test_a_dataset_with_no_usable_recording_fails_naming_the_problem(tmp_path):
    bad = _write(tmp_path / "b", [0.0, 0.1])
    (bad / "camera_ts.txt").write_text("0.1\n0.0\n")
    with pytest.raises(RecordingError, match="no usable recording"):
        ReplayCamera(tmp_path, realtime=False)


def _write_with_stream(path, times, shown):
    """A recording with a projector stream of 16x12 frames, each of grey level 10 x its index."""
    with RecordingWriter(path, name=path.name, width=8, height=6, fps=10.0) as writer:
        writer.set_projector(16, 12, 20.0)
        for k, t in enumerate(shown):
            writer.add_projector_frame(t, np.full((12, 16), 10 * k, np.uint8))
        for t in times:
            writer.add_frame(t, np.full((6, 8), 100, np.uint8))
    return path


def test_the_rear_replay_brings_each_recordings_projector_frames_on_the_cameras_clock(tmp_path):
    """`run --replay`: each frame carries the projector frames shown since the previous one, their times moved as
    the camera's (a later recording of a dataset is shifted), with the map beside the recording named."""
    _write_with_stream(tmp_path / "set" / "r1", [0.0, 0.1, 0.2], [-0.05, 0.0, 0.05, 0.1, 0.15, 0.25])
    _write_with_stream(tmp_path / "set" / "r2", [5.0, 5.1], [4.98, 5.03, 5.08])
    (tmp_path / "set" / "projector-calibration.npz").write_bytes(b"")  # only found here, not loaded
    frames = _drain(ReplayCamera(tmp_path / "set", realtime=False, projector_stream=True))
    shown = [[(round(t, 3), int(image[0, 0])) for t, image in f.shown] for f in frames]
    assert shown[:3] == [[(-0.05, 0), (0.0, 10)], [(0.05, 20), (0.1, 30)], [(0.15, 40)]]  # 0.25: after the last frame
    shift = frames[3].t - 5.0
    assert shown[3:] == [[(round(4.98 + shift, 3), 0)], [(round(5.03 + shift, 3), 10), (round(5.08 + shift, 3), 20)]]
    assert {f.stream.recording.name for f in frames} == {"r1", "r2"}
    assert all(f.stream.calibration == (tmp_path / "set" / "projector-calibration.npz").resolve() for f in frames)
    given = ReplayCamera(tmp_path / "set", realtime=False, projector_stream=True, calibration=tmp_path / "map.npz")
    assert _drain(given)[0].stream.calibration == tmp_path / "map.npz"
    plain = _drain(ReplayCamera(tmp_path / "set", realtime=False))  # the front camera's replay: no stream
    assert all(f.stream is None and f.shown == () for f in plain)
