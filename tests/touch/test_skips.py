"""`feelium replay` and `eval` leave bad recordings out, one line each, and score the good ones (exit 3)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from feelium.cli import main
from feelium.recording import Labels, RecordingWriter


def _good(path: Path, label: str = "empty") -> None:
    frame = np.full((48, 64), 180, np.uint8)
    with RecordingWriter(path, name=path.name, width=64, height=48, fps=15.0, roi=(8, 4, 40, 32)) as w:
        for i in range(8):
            w.add_frame(i / 15.0, frame)
        w.set_labels(Labels(label, False, None, ()))


def _break(path: Path, how: str) -> None:
    if how == "repeated time":
        ts = path / "camera_ts.txt"
        lines = ts.read_text().splitlines()
        ts.write_text("\n".join([lines[0], *lines[:-1]]) + "\n")
    elif how == "size":
        meta = json.loads((path / "meta.json").read_text())
        meta["camera"]["width"] = 128
        (path / "meta.json").write_text(json.dumps(meta))
    elif how == "roi":
        meta = json.loads((path / "meta.json").read_text())
        meta["roi"] = [0, 0, 65, 10]
        (path / "meta.json").write_text(json.dumps(meta))
    elif how == "encoding":
        ts = path / "camera_ts.txt"
        ts.write_bytes(b"\xe9" + ts.read_bytes())
    elif how == "labels":
        (path / "labels.json").write_text(json.dumps({"label": "empty", "target": "middle"}))


BROKEN = {"b-encoding": "encoding", "b-labels": "labels", "b-roi": "roi", "b-size": "size", "b-time": "repeated time"}
NAMED = {"b-encoding": "camera_ts.txt", "b-labels": "labels.json", "b-roi": "meta.json", "b-size": "meta.json", "b-time": "camera_ts.txt"}


@pytest.fixture
def dataset(tmp_path: Path) -> Path:
    for name in ("a-good", "c-good", *BROKEN):
        _good(tmp_path / name)
    for name, how in BROKEN.items():
        _break(tmp_path / name, how)
    return tmp_path


def _skip_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if ": skipped " in line]


@pytest.mark.parametrize("command", ["replay", "eval"])
def test_bad_recordings_are_named_skipped_and_summed_up(dataset, tmp_path, capsys, command):
    args = [command, str(dataset)] + (["--figure", str(tmp_path / "f.png")] if command == "eval" else [])
    assert main(args) == 3
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    lines = _skip_lines(err)
    assert len(lines) == len(BROKEN) + 1  # one per bad recording, then the summary
    for line, name in zip(lines, BROKEN):
        assert line.startswith(f"feelium {command}: skipped {dataset / name / NAMED[name]}: ")
    named = ", ".join(str(dataset / name / NAMED[name]) for name in BROKEN)
    assert lines[-1] == f"feelium {command}: skipped {len(BROKEN)} of {len(BROKEN) + 2} recordings: {named}"
    if command == "eval":
        assert "trials" in out and "2  (tp 0, fp 0, fn 0, tn 2)" in out


def test_a_clean_dataset_exits_0(tmp_path, capsys):
    _good(tmp_path / "a")
    assert main(["replay", str(tmp_path)]) == 0
    assert "skipped" not in capsys.readouterr().err


def test_a_video_shorter_than_its_times_is_skipped_while_replaying(tmp_path, capsys, monkeypatch):
    _good(tmp_path / "a")
    _good(tmp_path / "b")
    from feelium import recording

    real = recording.Recording.frames

    def short(self, *, gray=True):  # the video ends early: found only when decoding, not on open
        if self.path.name == "b":
            raise recording.RecordingError(self.path / "camera.mkv", "ended before its timestamps did")
        return real(self, gray=gray)

    monkeypatch.setattr(recording.Recording, "frames", short)
    assert main(["replay", str(tmp_path)]) == 3
    assert _skip_lines(capsys.readouterr().err)[0] == f"feelium replay: skipped {tmp_path / 'b' / 'camera.mkv'}: ended before its timestamps did"


def test_a_dataset_of_only_bad_recordings_exits_1_nothing_usable(tmp_path, capsys):
    _good(tmp_path / "b-time")
    _break(tmp_path / "b-time", "repeated time")
    assert main(["replay", str(tmp_path)]) == 1
    assert _skip_lines(capsys.readouterr().err)[-1].startswith("feelium replay: skipped 1 of 1 recordings: ")


def test_labels_that_contradict_their_take_are_skipped_by_eval_but_replay_plays_the_frames(tmp_path, capsys):
    """An 'empty' trial with a contact would count as a true negative (R15b F2); its frames are still frames."""
    _good(tmp_path / "a-good")
    _good(tmp_path / "b-odd")
    (tmp_path / "b-odd" / "labels.json").write_text(json.dumps({"label": "empty", "contacts": [{"t_on": 0.1, "t_off": 0.2}]}))
    assert main(["eval", str(tmp_path), "--figure", str(tmp_path / "f.png")]) == 3
    out, err = capsys.readouterr()
    (line, summary) = _skip_lines(err)
    assert line.startswith(f"feelium eval: skipped {tmp_path / 'b-odd' / 'labels.json'}: label 'empty' is a negative")
    assert "1  (tp 0, fp 0, fn 0, tn 1)" in out
    assert main(["replay", str(tmp_path)]) == 0
