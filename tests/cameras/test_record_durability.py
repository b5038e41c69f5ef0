"""`feelium record` never loses a take or leaves half of one: signals, a full disk, a failing final write."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from feelium import recording
from feelium.cameras.record import record
from feelium.cli import main
from feelium.recording import Recording
from tests.cameras.test_record import ScriptedCamera

ROOT = Path(__file__).resolve().parents[2]
MB = 1_000_000


class FillingDisk:
    """A disk that loses ``per_frame`` bytes with every frame written, starting with ``free`` bytes."""

    def __init__(self, free: int, per_frame: int) -> None:
        self.free, self.per_frame = free, per_frame

    def __call__(self, path: Path) -> int:
        left = self.free
        self.free -= self.per_frame
        return left


def _leftovers(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


def test_a_filling_disk_ends_the_take_short_and_valid(tmp_path):
    disk = FillingDisk(free=recording.RESERVE_BYTES + 3 * MB + 1, per_frame=MB)  # room for four frames
    take = record(ScriptedCamera([i / 10 for i in range(20)]), tmp_path / "r", seconds=None, fps=10.0, name="r",
                  writer_options={"free": disk})  # fmt: skip
    assert take.ended == "disk full" and "disk nearly full" in take.problem
    assert take.frames == 4 and len(Recording(take.path)) == 4
    assert _leftovers(tmp_path) == ["r"]


def test_a_disk_full_before_the_first_frame_keeps_no_empty_take(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(recording, "free_bytes", lambda path: recording.RESERVE_BYTES - 1)
    out = tmp_path / "r"
    assert main(["record", "--sim", "--out", str(out), "--seconds", "5"]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("feelium record:")]
    assert len(err) == 1 and err[0].startswith(f"feelium record: cannot write {out}: disk nearly full") and "nothing kept" in err[0]
    assert _leftovers(tmp_path) == []


def test_progress_to_a_terminal_that_hung_up_costs_neither_the_take_nor_the_exit_code(tmp_path, monkeypatch):
    """A dropped SSH session: every write to the terminal fails with EIO, the SIGHUP finishes the take."""

    class HungUp:
        def write(self, _text: str) -> int:
            raise OSError(errno.EIO, "Input/output error")

        def flush(self) -> None:
            raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(sys, "stderr", HungUp())
    monkeypatch.setattr(sys, "stdout", HungUp())
    out = tmp_path / "r"
    assert main(["record", "--sim", "--out", str(out), "--seconds", "6"]) == 0  # progress is due at 5 s
    assert Recording(out).timestamps[-1] > 5.0 and _leftovers(tmp_path) == ["r"]


def test_the_record_command_says_so_in_one_line_and_keeps_the_take(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(recording, "free_bytes", FillingDisk(free=recording.RESERVE_BYTES + 5 * MB, per_frame=MB))
    out = tmp_path / "r"
    assert main(["record", "--sim", "--out", str(out), "--seconds", "5"]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("feelium record:")]
    free = (recording.RESERVE_BYTES - MB) / 1e6  # six frames fit above the reserve, the seventh does not
    assert err == [f"feelium record: disk nearly full ({free:.1f} MB free) in {tmp_path}: kept a shorter take {out} (6 frames, 0.3 s)"]
    assert len(Recording(out)) == 6 and _leftovers(tmp_path) == ["r"]


def _enospc_after(limit: int):
    """``write_durably`` on a disk that takes ``limit`` more bytes, then fails like a full one."""
    real = recording.write_durably
    room = {"left": limit}

    def write(path: Path, data: bytes) -> None:
        if len(data) > room["left"]:
            path.write_bytes(data[: room["left"]])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        room["left"] -= len(data)
        real(path, data)

    return write


def test_no_room_for_the_closing_files_leaves_nothing_and_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(recording, "write_durably", _enospc_after(40))  # the times fit, meta.json does not
    out = tmp_path / "r"
    assert main(["record", "--sim", "--out", str(out), "--seconds", "0.3"]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("feelium record:")]
    assert err == [f"feelium record: cannot write {out}: No space left on device; nothing kept"]
    assert _leftovers(tmp_path) == []  # neither the take nor its temp dir


def test_close_fsyncs_every_file_and_both_directories(tmp_path, monkeypatch):
    synced: list[str] = []
    real = os.fsync

    def fsync(fd: int) -> None:
        synced.append(os.readlink(f"/proc/self/fd/{fd}"))
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    take = record(ScriptedCamera([0.0, 0.1]), tmp_path / "r", seconds=None, fps=10.0, name="r")
    names = [Path(p).name for p in synced]
    assert {"camera_ts.txt", "meta.json", "camera.mkv"} <= set(names)
    assert any(n.startswith(".r.") for n in names)  # the temp dir, before the rename
    assert synced[-1] == str(tmp_path)  # the parent, after it: the new name is durable
    assert take.path == tmp_path / "r"


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_a_stop_signal_finishes_a_valid_shorter_take(tmp_path, sig):
    out = tmp_path / "r"
    proc = subprocess.Popen(
        [sys.executable, "-m", "feelium", "record", "--sim", "--out", str(out), "--seconds", "60"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 30
        while not any(p.name.startswith(".r.") for p in tmp_path.iterdir()):
            assert proc.poll() is None and time.monotonic() < deadline, "the take never started"
            time.sleep(0.05)
        time.sleep(0.5)  # a few frames
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr
    assert f"stopped by {sig.name}" in stdout
    rec = Recording(out)
    assert len(rec) >= 2 and np.all(np.diff(rec.timestamps) > 0)
    assert _leftovers(tmp_path) == ["r"]


class StallingCamera(ScriptedCamera):
    """Delivers its frames, then blocks in ``read()`` for ever, as ``capture_request()`` does with no frame coming."""

    def __init__(self, times):
        super().__init__(times)
        self.blocked = threading.Event()

    def read(self):
        if not self.times:
            self.blocked.set()
            threading.Event().wait()  # never returns (a daemon thread, abandoned)
        return super().read()


def test_a_camera_that_stops_delivering_ends_the_take_kept_and_said(tmp_path):
    camera = StallingCamera([i / 10 for i in range(5)])
    take = record(camera, tmp_path / "r", seconds=None, fps=10.0, name="r", stall_s=0.3)
    assert take.ended == "camera stalled" and "no frame for 0.3 s" in take.problem
    assert take.frames == 5 and len(Recording(take.path)) == 5 and _leftovers(tmp_path) == ["r"]


def test_a_stop_request_during_a_read_that_never_returns_still_finishes_the_take(tmp_path):
    camera = StallingCamera([i / 10 for i in range(5)])
    stop = threading.Event()
    threading.Thread(target=lambda: camera.blocked.wait() and stop.set(), daemon=True).start()
    started = time.monotonic()
    take = record(camera, tmp_path / "r", seconds=None, fps=10.0, name="r", stop=stop, stall_s=60.0)
    assert take.ended == "stopped" and take.frames == 5 and len(Recording(take.path)) == 5
    assert time.monotonic() - started < 30.0  # not the 60 s stall limit: the stop was heard while the read hung
