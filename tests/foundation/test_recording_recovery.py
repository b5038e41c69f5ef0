"""A take whose process was killed (SIGKILL, a power cut, the OOM killer) is recovered, not lost (R15b F4)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from feelium.recording import JOURNAL_META, Recording, RecordingWriter, recover_interrupted

# A writer in a child process that writes frames until it is killed, printing each frame's count.
WRITER = """
import sys, numpy as np
from feelium.recording import RecordingWriter
w = RecordingWriter(sys.argv[1], name="take", width=64, height=48, fps=30.0, roi=(8, 4, 40, 32))
rng = np.random.default_rng(1)
i = 0
while True:
    w.add_frame(i / 30.0, rng.integers(0, 256, (48, 64), dtype=np.uint8))
    i += 1
    print(i, flush=True)
"""


def _killed_take(parent: Path, frames: int) -> Path:
    """Write ``frames`` or more frames in a child process, then SIGKILL it; the hidden temp dir it left."""
    child = subprocess.Popen([sys.executable, "-c", WRITER, str(parent / "take")], stdout=subprocess.PIPE, text=True,
                             env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])})  # fmt: skip
    assert child.stdout is not None
    for line in child.stdout:
        if int(line) >= frames:
            break
    child.send_signal(signal.SIGKILL)
    child.wait(10)
    (temp,) = [p for p in parent.iterdir() if p.name.startswith(".take.")]
    return temp


@pytest.mark.slow
def test_a_killed_take_is_recovered_with_the_frames_its_video_holds(tmp_path):
    temp = _killed_take(tmp_path, 400)  # more than FFmpeg keeps in its last, unwritten cluster
    assert not (tmp_path / "take").exists()  # nothing looks whole before recovery
    (found,) = recover_interrupted(tmp_path)
    assert found.temp == temp and found.path == tmp_path / "take-recovered" and found.frames > 0
    recording = Recording(found.path)  # a valid recording: sizes, times and frame count agree
    assert len(recording) == found.frames
    assert np.allclose(recording.timestamps, np.arange(found.frames) / 30.0, atol=1e-6)
    assert recording.meta.roi == (8, 4, 40, 32)
    assert not any(p.name.startswith(".") for p in found.path.iterdir())  # the journal and set-aside are gone
    assert not temp.exists()
    assert recover_interrupted(tmp_path) == []  # done once


def test_a_take_still_being_written_is_left_alone_and_a_frameless_one_is_removed(tmp_path):
    writer = RecordingWriter(tmp_path / "live", name="live", width=64, height=48, fps=30.0)
    writer.add_frame(0.0, np.zeros((48, 64), np.uint8))
    assert recover_interrupted(tmp_path) == []  # its writer (this process) is alive
    writer.close()
    empty = RecordingWriter(tmp_path / "empty", name="empty", width=64, height=48, fps=30.0)
    empty._journal.close()  # as if killed before its first frame
    empty._video.release()
    (found,) = recover_interrupted(tmp_path, alive=lambda pid: False)
    assert found.path is None and found.frames == 0 and not found.temp.exists()
    assert (tmp_path / "live").is_dir()


def test_recovered_names_do_not_overwrite(tmp_path):
    (tmp_path / "take-recovered").mkdir()
    writer = RecordingWriter(tmp_path / "take", name="take", width=64, height=48, fps=30.0)
    for i in range(3):
        writer.add_frame(i / 30.0, np.full((48, 64), 7 * i, np.uint8))
    writer._journal.close()
    writer._video.release()  # the video is whole here: every frame counts
    header = json.loads((writer._tmp / JOURNAL_META).read_text())
    assert header["target"] == "take" and header["pid"] == os.getpid()
    (found,) = recover_interrupted(tmp_path, alive=lambda pid: False)
    assert found.path == tmp_path / "take-recovered-2" and found.frames == 3
    assert len(Recording(found.path)) == 3


def test_a_finished_take_keeps_no_journal(tmp_path):
    with RecordingWriter(tmp_path / "t", name="t", width=64, height=48, fps=30.0) as writer:
        writer.add_frame(0.0, np.zeros((48, 64), np.uint8))
    assert sorted(p.name for p in (tmp_path / "t").iterdir()) == ["camera.mkv", "camera_ts.txt", "meta.json"]



def test_a_killed_writer_not_yet_reaped_counts_as_gone(tmp_path):
    """A zombie answers kill(pid, 0) but writes nothing more: its take is recovered."""
    from feelium.recording import _process_alive

    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        assert _process_alive(child.pid)
        child.send_signal(signal.SIGKILL)
        deadline = time.monotonic() + 10
        while _process_alive(child.pid) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not _process_alive(child.pid)  # still a zombie: not waited for yet
        assert Path(f"/proc/{child.pid}").exists()
    finally:
        child.wait(10)
