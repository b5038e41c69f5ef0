"""Recording format v1: the writer is atomic and the reader rejects malformed recordings clearly."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from feelium import recording
from feelium.recording import (
    Contact,
    Labels,
    Recording,
    RecordingError,
    RecordingWriter,
    ThermalData,
    check_labels_fit,
    find_recordings,
)


def _write(path, n=6, **kwargs):
    rng = np.random.default_rng(3)
    frames = [rng.integers(0, 256, (48, 64), dtype=np.uint8) for _ in range(n)]
    with RecordingWriter(path, name=path.name, width=64, height=48, fps=15.0, roi=(8, 4, 40, 32), **kwargs) as w:
        for i, f in enumerate(frames):
            w.add_frame(i / 15.0, f)
        w.set_labels(Labels("tap", False, (20.0, 20.0), (Contact(0.1, 0.3, np.array([[0.1, 20, 20], [0.3, 22, 21]])),)))
    return frames


def test_round_trip_is_lossless(tmp_path):
    frames = _write(tmp_path / "r")
    rec = Recording(tmp_path / "r")
    assert len(rec) == len(frames)
    assert rec.meta.roi == (8, 4, 40, 32)
    got = list(rec.frames())
    assert all(np.array_equal(f, g) for f, (_, g) in zip(frames, got))
    assert [t for t, _ in got] == pytest.approx([i / 15.0 for i in range(len(frames))], abs=1e-6)
    assert rec.labels is not None and rec.labels.label == "tap"
    assert rec.labels.contacts[0].position_at(0.2) == pytest.approx((21.0, 20.5))


def test_bgr_frames_decode_to_gray_or_colour(tmp_path):
    with RecordingWriter(tmp_path / "c", name="c", width=32, height=24, fps=10, pixel_format="bgr8") as w:
        w.add_frame(0.0, np.full((24, 32, 3), (10, 200, 30), np.uint8))
    rec = Recording(tmp_path / "c")
    (_, colour), = list(rec.frames(gray=False))
    (_, gray), = list(rec.frames(gray=True))
    assert colour.shape == (24, 32, 3) and gray.shape == (24, 32)
    assert tuple(colour[0, 0]) == (10, 200, 30)


def test_crash_inside_writer_leaves_nothing(tmp_path):
    with pytest.raises(RuntimeError):
        with RecordingWriter(tmp_path / "x", name="x", width=32, height=24, fps=10) as w:
            w.add_frame(0.0, np.zeros((24, 32), np.uint8))
            raise RuntimeError("power cut")
    assert list(tmp_path.iterdir()) == []


def test_writer_rejects_backwards_time_and_wrong_size(tmp_path):
    with RecordingWriter(tmp_path / "w", name="w", width=32, height=24, fps=10) as w:
        w.add_frame(1.0, np.zeros((24, 32), np.uint8))
        with pytest.raises(ValueError, match="backwards"):
            w.add_frame(0.5, np.zeros((24, 32), np.uint8))
        with pytest.raises(ValueError, match="frame is"):
            w.add_frame(2.0, np.zeros((10, 10), np.uint8))


def test_timestamp_count_mismatch_is_named(tmp_path):
    _write(tmp_path / "r")
    ts = tmp_path / "r" / "camera_ts.txt"
    ts.write_text(ts.read_text() + "9.0\n")
    with pytest.raises(RecordingError, match="7 timestamps but camera.mkv has 6 frames"):
        Recording(tmp_path / "r")


def test_counting_packets_on_open_agrees_with_decoding_even_on_a_cut_video(tmp_path):
    """Recording() counts camera.mkv's frames as packets, undecoded (a full decode per open was a third of the
    touch end-to-end tests' time): the same count as decoding them, on the whole file and cut anywhere."""
    _write(tmp_path / "r", n=12)
    data = (tmp_path / "r" / "camera.mkv").read_bytes()
    cut = tmp_path / "cut.mkv"
    for end in (len(data), *range(len(data) // 10, len(data), len(data) // 10)):
        cut.write_bytes(data[:end])
        assert recording._probe_video(cut, decode=False) == recording._probe_video(cut), end
    assert recording._probe_video(tmp_path / "r" / "camera.mkv", decode=False) == (12, (64, 48))


def test_timestamps_that_are_not_utf8_are_named_not_a_traceback(tmp_path):
    _write(tmp_path / "r")
    ts = tmp_path / "r" / "camera_ts.txt"
    ts.write_bytes(b"\xe9" + ts.read_bytes())
    with pytest.raises(RecordingError, match=r"camera_ts.txt.*not UTF-8 text \(byte 0\)"):
        Recording(tmp_path / "r")


def test_backwards_timestamps_are_named(tmp_path):
    _write(tmp_path / "r")
    ts = tmp_path / "r" / "camera_ts.txt"
    lines = ts.read_text().splitlines()
    lines[3] = "0.0"
    ts.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match="line 4: time goes backwards"):
        Recording(tmp_path / "r")


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"version": 2}, "unknown version 2"),
        ({"format": "other"}, "format must be"),
        ({"roi": [0, 0, 999, 10]}, "does not fit"),
        ({"camera": {"width": 64}}, "camera: missing or bad field"),
        ({"roi": ["a", 0, 10, 10]}, "roi: expected"),
        ({"roi": [0.5, 0, 10, 10]}, "whole pixels"),
        ({"camera": {"width": 64, "height": 48, "fps": 0, "pixel_format": "gray8"}}, "camera.fps must be"),
        ({"camera": {"width": 128, "height": 48, "fps": 15.0, "pixel_format": "gray8"}}, "camera.mkv holds 64x48"),
    ],
)
def test_bad_meta_is_named(tmp_path, patch, message):
    _write(tmp_path / "r")
    meta_path = tmp_path / "r" / "meta.json"
    meta = json.loads(meta_path.read_text())
    meta.update(patch)
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(RecordingError, match=message) as info:
        Recording(tmp_path / "r")
    assert "meta.json" in str(info.value)


def test_missing_video_and_bad_labels(tmp_path):
    _write(tmp_path / "r")
    (tmp_path / "r" / "labels.json").write_text(json.dumps({"label": "poke", "contacts": []}))
    with pytest.raises(RecordingError, match="label 'poke'"):
        Recording(tmp_path / "r")
    (tmp_path / "r" / "camera.mkv").unlink()
    with pytest.raises(RecordingError, match="camera.mkv: missing file"):
        Recording(tmp_path / "r")


def test_unknown_meta_keys_are_ignored(tmp_path):
    _write(tmp_path / "r", extra_meta={"generator": {"seed": 5}})
    assert Recording(tmp_path / "r").meta.raw["generator"] == {"seed": 5}


def test_thermal_round_trip_and_dataset_discovery(tmp_path):
    with RecordingWriter(tmp_path / "set" / "a", name="a", width=32, height=24, fps=10) as w:
        w.add_frame(0.0, np.zeros((24, 32), np.uint8))
        celsius = np.full((2, 24, 32), 22.5, np.float32)
        celsius[1, 3, 4] = np.nan
        w.set_thermal(ThermalData(t=np.array([0.0, 0.125]), celsius=celsius), fps=8.0)
    _write(tmp_path / "set" / "b" / "nested")
    found = find_recordings(tmp_path / "set")
    assert [p.name for p in found] == ["a", "nested"]
    thermal = Recording(found[0]).thermal()
    assert thermal is not None and np.isnan(thermal.celsius[1, 3, 4])
    assert Recording(found[0]).meta.thermal == {"width": 32, "height": 24, "fps": 8.0}
    (tmp_path / "empty").mkdir()
    with pytest.raises(RecordingError, match="holds no recording"):
        find_recordings(tmp_path / "empty")
    with pytest.raises(RecordingError, match="no such file"):
        find_recordings(tmp_path / "absent")


def test_repeated_timestamps_are_named(tmp_path):
    _write(tmp_path / "r")
    ts = tmp_path / "r" / "camera_ts.txt"
    lines = ts.read_text().splitlines()
    lines[3] = lines[2]
    ts.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match=r"camera_ts.txt: line 4: time repeats"):
        Recording(tmp_path / "r")


@pytest.mark.parametrize(
    ("labels", "message"),
    [
        ({"label": "tap", "target": ["x", 1]}, "target: expected"),
        ({"label": "tap", "contacts": {"t_on": 1}}, "contacts: expected a list"),
        ({"label": "tap", "contacts": [3]}, r"contacts\[0\]: needs numeric"),
        ({"label": "tap", "contacts": [{"t_on": "1", "t_off": 2}]}, r"contacts\[0\]: needs numeric"),
        ({"label": "tap", "contacts": [{"t_on": 1, "t_off": 2, "path": [[1, 2, 3], [1, 2]]}]}, r"contacts\[0\].path"),
        ({"label": "tap", "contacts": [{"t_on": 1, "t_off": 2, "path": [[1, "a", 3]]}]}, r"contacts\[0\].path"),
    ],
)
def test_bad_labels_are_named_not_a_traceback(tmp_path, labels, message):
    _write(tmp_path / "r")
    (tmp_path / "r" / "labels.json").write_text(json.dumps(labels))
    with pytest.raises(RecordingError, match=message) as info:
        Recording(tmp_path / "r")
    assert "labels.json" in str(info.value)


@pytest.mark.parametrize(
    ("labels", "message"),
    [
        ({"label": "tap", "target": [5000, -30], "contacts": [{"t_on": 0.1, "t_off": 0.2}]}, "outside the 64x48 camera frame"),
        ({"label": "tap", "contacts": [{"t_on": 100, "t_off": 101}]}, r"contacts\[0\]: 100.0-101.0 s lies outside the take"),
        ({"label": "tap", "contacts": []}, "'tap' needs at least one entry in contacts"),
        ({"label": "hold"}, "'hold' needs at least one entry in contacts"),
        ({"label": "empty", "contacts": [{"t_on": 0.1, "t_off": 0.2}]}, "'empty' is a negative: its contacts must be empty"),
        ({"label": "contact", "clip": True}, "'contact' needs at least one entry"),
        ({"label": "hover", "clip": True, "contacts": [{"t_on": 0.1, "t_off": 0.2}]}, "'hover' is a negative"),
    ],
)
def test_labels_that_contradict_themselves_or_their_take_are_refused_for_scoring(tmp_path, labels, message):
    """They would otherwise be scored as if true (an 'empty' with a contact counted as a true negative); the
    frames still replay (opening does not check what only scoring needs)."""
    _write(tmp_path / "r")
    (tmp_path / "r" / "labels.json").write_text(json.dumps(labels))
    recording = Recording(tmp_path / "r")
    with pytest.raises(RecordingError, match=message) as info:
        check_labels_fit(recording)
    assert "labels.json" in str(info.value)


def test_labels_that_fit_their_take_are_accepted_with_overlapping_contacts(tmp_path):
    """Two hands at once overlap in time; a target on the frame's edge is in it."""
    _write(tmp_path / "r")
    both = [{"t_on": 0.0, "t_off": 0.3, "contact": "finger"}, {"t_on": 0.1, "t_off": 0.5, "contact": "palm"}]
    (tmp_path / "r" / "labels.json").write_text(json.dumps({"label": "hold", "target": [64, 0], "contacts": both}))
    recording = Recording(tmp_path / "r")
    check_labels_fit(recording)
    assert len(recording.labels.contacts) == 2


def test_the_projector_stream_round_trips_beside_the_camera(tmp_path):
    """What the projector showed is kept losslessly with its own display times (the spec's projector.mkv)."""
    rng = np.random.default_rng(5)
    shown = [rng.integers(0, 256, (36, 80), dtype=np.uint8) for _ in range(5)]
    with RecordingWriter(tmp_path / "p", name="p", width=64, height=48, fps=15.0) as w:
        w.set_projector(80, 36, 30.0)
        for i in range(3):
            w.add_frame(i / 15.0, np.zeros((48, 64), np.uint8))
        for k, frame in enumerate(shown):
            w.add_projector_frame(-0.1 + k / 30.0, frame)
        with pytest.raises(ValueError, match="backwards"):
            w.add_projector_frame(-0.5, shown[0])
        with pytest.raises(ValueError, match="projector frame is"):
            w.add_projector_frame(1.0, np.zeros((36, 81), np.uint8))
    rec = Recording(tmp_path / "p")
    assert rec.has_projector and rec.meta.raw["projector"] == {"width": 80, "height": 36, "fps": 30.0, "pixel_format": "gray8"}
    got = list(rec.projector_frames())
    assert [t for t, _ in got] == pytest.approx([-0.1 + k / 30.0 for k in range(5)], abs=1e-6)
    assert all(np.array_equal(a, b) for a, (_, b) in zip(shown, got))
    assert not Recording(_write_plain(tmp_path / "q")).has_projector


def _write_plain(path):
    _write(path)
    return path


def test_a_projector_stream_of_another_size_than_its_meta_is_named(tmp_path):
    with RecordingWriter(tmp_path / "p", name="p", width=64, height=48, fps=15.0) as w:
        w.set_projector(80, 36, 30.0)
        w.add_frame(0.0, np.zeros((48, 64), np.uint8))
        w.add_projector_frame(0.0, np.zeros((36, 80), np.uint8))
    meta = json.loads((tmp_path / "p" / "meta.json").read_text())
    meta["projector"]["width"] = 96
    (tmp_path / "p" / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(RecordingError, match="meta.projector says 96x36"):
        list(Recording(tmp_path / "p").projector_frames())


def test_a_contact_may_say_what_touched(tmp_path):
    """The optional ``contact`` key (finger, palm, hug) round-trips; anything else is named."""
    _write(tmp_path / "r")
    labels = {"label": "hold", "target": None, "contacts": [{"t_on": 0.1, "t_off": 0.3, "contact": "palm"}, {"t_on": 0.1, "t_off": 0.2}]}
    (tmp_path / "r" / "labels.json").write_text(json.dumps(labels))
    got = Recording(tmp_path / "r").labels
    assert got is not None and [c.contact for c in got.contacts] == ["palm", None]
    assert got.to_json()["contacts"][0]["contact"] == "palm" and "contact" not in got.to_json()["contacts"][1]
    labels["contacts"][0]["contact"] = "elbow"
    (tmp_path / "r" / "labels.json").write_text(json.dumps(labels))
    with pytest.raises(RecordingError, match="contacts\\[0\\].contact: 'elbow'"):
        Recording(tmp_path / "r")


def test_a_finished_take_is_shared_as_the_umask_says_not_left_0700(tmp_path):
    import os
    import stat

    old = os.umask(0o027)
    try:
        _write(tmp_path / "r")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "r").stat().st_mode) == 0o750


def test_labels_may_say_when_the_light_was_switched(tmp_path):
    """The optional ``light_switches`` (seconds on the camera clock) round-trips, sorted; anything but numbers is
    named. ``eval`` measures recovery after a switch from it."""
    _write(tmp_path / "r")
    labels = {"label": "empty", "target": None, "contacts": [], "light_switches": [1.5, 0.25]}
    (tmp_path / "r" / "labels.json").write_text(json.dumps(labels))
    got = Recording(tmp_path / "r").labels
    assert got is not None and got.light_switches == (0.25, 1.5)
    assert got.to_json()["light_switches"] == [0.25, 1.5]
    assert "light_switches" not in dataclasses.replace(got, light_switches=()).to_json()
    labels["light_switches"] = ["at noon"]
    (tmp_path / "r" / "labels.json").write_text(json.dumps(labels))
    with pytest.raises(RecordingError, match="light_switches: expected a list of times"):
        Recording(tmp_path / "r")
