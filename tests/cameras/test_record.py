"""`feelium record`: camera frames with their own timestamps into a valid recording, atomically."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.cameras.base import Frame
from feelium.cameras.record import record
from feelium.cli import main
from feelium.recording import Recording, ThermalData


class ScriptedCamera:
    name = "scripted"
    realtime = True

    def __init__(self, times, fail_at=None, exc=None):
        self.times = list(times)
        self.fail_at, self.exc = fail_at, exc
        self.reads = 0

    def read(self):
        self.reads += 1
        if self.fail_at is not None and self.reads == self.fail_at:
            raise self.exc
        if not self.times:
            return None
        t = self.times.pop(0)
        return Frame(t=t, image=np.full((6, 8), int(t * 10) % 256, np.uint8), roi=(1, 1, 4, 4))

    def close(self):
        pass


def test_records_until_the_time_limit_with_the_cameras_timestamps(tmp_path):
    camera = ScriptedCamera([10.0, 10.07, 10.13, 10.2, 10.27, 10.33, 10.4])
    path = record(camera, tmp_path / "r", seconds=0.3, fps=15.0, name="r", session="lab").path
    rec = Recording(path)
    assert rec.timestamps.tolist() == pytest.approx([0.0, 0.07, 0.13, 0.2, 0.27])
    assert rec.meta.roi == (1, 1, 4, 4) and rec.meta.session == "lab" and rec.meta.source == "device"
    assert rec.meta.camera.pixel_format == "gray8"


def test_a_repeated_timestamp_is_dropped_so_the_file_stays_valid(tmp_path):
    path = record(ScriptedCamera([0.0, 0.1, 0.1, 0.2]), tmp_path / "r", seconds=None, fps=10.0, name="r").path
    assert Recording(path).timestamps.tolist() == pytest.approx([0.0, 0.1, 0.2])


def test_ctrl_c_finishes_the_recording_but_a_crash_leaves_nothing(tmp_path):
    path = record(
        ScriptedCamera([0.0, 0.1, 0.2], fail_at=3, exc=KeyboardInterrupt()), tmp_path / "ok", seconds=None, fps=10.0, name="ok"
    ).path
    assert len(Recording(path)) == 2
    with pytest.raises(OSError):
        record(ScriptedCamera([0.0, 0.1, 0.2], fail_at=3, exc=OSError("gone")), tmp_path / "bad", seconds=None, fps=10.0, name="b")
    assert not (tmp_path / "bad").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["ok"]  # no half recording or temp dir left behind


def test_the_thermal_seam_writes_thermal_npz(tmp_path):
    class Thermal:
        fps = 8.0

        def __init__(self):
            self.t = []

        def sample(self, t):
            self.t.append(t)

        def result(self):
            return ThermalData(t=np.array(self.t), celsius=np.full((len(self.t), 24, 32), 21.0, np.float32))

    path = record(ScriptedCamera([0.0, 0.1, 0.2]), tmp_path / "r", seconds=None, fps=10.0, name="r", thermal=Thermal()).path
    thermal = Recording(path).thermal()
    assert thermal is not None and thermal.t.tolist() == pytest.approx([0.0, 0.1, 0.2])


@pytest.mark.slow
def test_record_command_on_the_simulator(tmp_path):
    out = tmp_path / "sim-rec"
    assert main(["record", "--sim", "--out", str(out), "--seconds", "1", "--name", "x"]) == 0
    rec = Recording(out)
    assert rec.meta.name == "x" and rec.meta.source == "synthetic" and rec.meta.raw["recorder"]["backend"] == "sim"
    assert 12 <= len(rec) <= 16 and np.all(np.diff(rec.timestamps) > 0)
    assert main(["record", "--sim", "--out", str(out), "--seconds", "1"]) == 1  # never overwrites


def test_record_on_a_pi_without_its_camera_fails_instead_of_recording_the_simulator(tmp_path, monkeypatch, capsys):
    """``auto`` on the blimp means the camera: a missing one is a clear error, never a synthetic take."""
    import feelium.daemon.backends as backends

    monkeypatch.setattr(backends, "on_raspberry_pi", lambda: True)  # and no picamera2 here: no camera
    out = tmp_path / "take"
    assert main(["record", "--out", str(out), "--seconds", "1"]) == 1
    assert not out.exists()
    assert "simulator" not in capsys.readouterr().err


def test_record_off_a_pi_says_it_records_the_simulator(tmp_path, monkeypatch, capsys):
    import feelium.daemon.backends as backends

    monkeypatch.setattr(backends, "on_raspberry_pi", lambda: False)
    assert main(["record", "--out", str(tmp_path / "take"), "--seconds", "0.5"]) == 0
    assert "recording the scene simulator" in capsys.readouterr().err
