"""The synthetic fisheye room the headset sees without hardware."""

from __future__ import annotations

import numpy as np

from feelium.cameras.sim import SimFrontCamera
from feelium.cameras.sim_front import SimFisheyeRoom


def test_frames_are_bgr_with_a_dark_border_outside_the_fisheye_circle():
    frame = SimFisheyeRoom(160, 120).frame(1.0)
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame[0, 0].sum() == 0 and frame[0, -1].sum() == 0  # corners lie outside the image circle
    assert frame[60, 80].sum() > 0


def test_the_view_moves_over_time_and_is_deterministic():
    room = SimFisheyeRoom(160, 120, seed=3)
    a, b = room.frame(0.0), room.frame(2.0)
    assert np.mean(np.abs(a.astype(int) - b.astype(int))) > 2.0
    assert np.array_equal(SimFisheyeRoom(160, 120, seed=3).frame(2.0), b)


def test_sim_front_camera_paces_and_stamps_frames():
    now = [0.0]

    def sleep(seconds):
        now[0] += seconds

    camera = SimFrontCamera(64, 48, 10.0, clock=lambda: now[0], sleep=sleep)
    frames = [camera.read() for _ in range(3)]
    assert [round(f.t, 6) for f in frames] == [0.0, 0.1, 0.2]
    camera.close()
    assert camera.read() is None
