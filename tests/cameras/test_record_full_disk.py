"""A real full disk in the middle of a take: a small tmpfs in a private mount namespace (``unshare -rm``).

The disk is filled by someone else between two frames, as another process on
the blimp would. What must be on disk afterwards: a take that ``Recording``
opens (its timestamps cut to the frames the video holds) and no temp dir.
Skipped where unprivileged mount namespaces are not allowed.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FRAMES = 60  # offered by the camera; the disk fills after FILL_AT of them
FILL_AT = 20

SCENARIO = r"""
import json, os, sys
import numpy as np
from feelium.cameras.base import Frame
from feelium.cameras.record import record
from feelium.recording import Recording

disk, leave = sys.argv[1], int(sys.argv[2])
rng = np.random.default_rng(7)
images = iter(rng.integers(0, 256, (FRAMES, 240, 320), dtype=np.uint8))  # noise: ~80 kB a frame in FFV1


class Camera:
    name, realtime = "noise", True

    def __init__(self):
        self.i = 0

    def read(self):
        if self.i == FRAMES:
            return None
        self.i += 1
        return Frame(t=self.i / 10, image=next(images), roi=None)

    def close(self):
        pass


def fill(frames, t):
    if frames == FILL_AT:  # someone else takes the disk but ``leave`` bytes
        st = os.statvfs(disk)
        with open(os.path.join(disk, "other"), "wb") as f:
            f.write(bytes(max(0, st.f_bavail * st.f_frsize - leave)))


take = record(Camera(), __import__("pathlib").Path(disk) / "take", seconds=None, fps=10.0, name="take",
              on_frame=fill, writer_options={"reserve_bytes": 64 * 1024})
rec = Recording(take.path)
frames = sum(1 for _ in rec.frames())
print(json.dumps({"ended": take.ended, "problem": take.problem, "frames": take.frames, "seconds": take.seconds,
                  "timestamps": len(rec), "decoded": frames, "last_t": float(rec.timestamps[-1]),
                  "left": sorted(os.listdir(disk)), "take_files": sorted(os.listdir(take.path))}))
""".replace("FRAMES", str(FRAMES)).replace("FILL_AT", str(FILL_AT))


def _in_a_small_tmpfs(tmp_path: Path, leave: int) -> dict:
    mount = tmp_path / "disk"
    mount.mkdir()
    script = tmp_path / "scenario.py"
    script.write_text(SCENARIO)
    shell = f"mount -t tmpfs -o size=16m tmpfs {mount} && exec {sys.executable} {script} {mount} {leave}"
    done = subprocess.run(["unshare", "-rm", "sh", "-c", shell], capture_output=True, text=True, timeout=60,
                          cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "OPENCV_LOG_LEVEL": "ERROR"})
    if done.returncode != 0 and "mount" in done.stderr and "Traceback" not in done.stderr:
        pytest.skip(f"no private tmpfs here: {done.stderr.strip()[:200]}")
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


needs_unshare = pytest.mark.skipif(shutil.which("unshare") is None, reason="unshare (util-linux) is not installed")


@needs_unshare
def test_a_disk_taken_whole_by_another_process_keeps_every_frame_written(tmp_path):
    """Nothing left at all: the next frame stops the take, and the room set aside at its start lets FFmpeg
    write the cluster it still held, the index, the timestamps and meta.json."""
    out = _in_a_small_tmpfs(tmp_path, leave=0)
    assert out["ended"] == "disk full" and "disk nearly full" in out["problem"]
    assert out["frames"] == FILL_AT == out["timestamps"] == out["decoded"]
    assert out["last_t"] == pytest.approx(out["seconds"]) == pytest.approx((FILL_AT - 1) / 10)
    assert out["left"] == ["other", "take"]  # no temp dir, no set-aside file
    assert out["take_files"] == ["camera.mkv", "camera_ts.txt", "meta.json"]


@needs_unshare
def test_a_disk_left_just_above_the_stop_line_loses_frames_in_ffmpeg_and_the_take_is_cut_to_them(tmp_path):
    """Room for the free-space check but not for FFmpeg's next cluster: FFmpeg's write fails (and every later
    one), so the video holds fewer frames than were handed to it; the times are cut to the decodable frames."""
    out = _in_a_small_tmpfs(tmp_path, leave=200 * 1024)
    assert out["ended"] == "disk full" and out["problem"]
    assert 0 < out["frames"] == out["timestamps"] == out["decoded"] < FRAMES
    assert out["last_t"] == pytest.approx(out["seconds"])
    assert out["left"] == ["other", "take"]
