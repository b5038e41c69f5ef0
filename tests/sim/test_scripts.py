"""Trial scripts: timing per class, hover never touches, tremor frequency, determinism per seed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from feelium.lab.sim import scripts
from feelium.sim.hand_paths import HOVER_FLOOR_MM, HandTrack, Keyframe, Tremor, min_jerk
from feelium.lab.sim.protocol import Item, build_script, plan, recording_rng, render_frames
from feelium.sim.sessions import session_presets
from feelium.sim.scene import ROI

TARGET = (320.0, 240.0)


def _scripts(builder, n=30):
    return [builder(np.random.default_rng(i), TARGET, (0.0, 0.0), ROI) for i in range(n)]


def test_min_jerk_endpoints() -> None:
    assert min_jerk(0.0) == 0.0 and min_jerk(1.0) == 1.0 and min_jerk(0.5) == pytest.approx(0.5)


def test_tap_hold_swipe_timing_and_paths() -> None:
    for s in _scripts(scripts.tap):
        (c,) = s.labels().contacts
        assert 0.1 - 1e-3 <= c.t_off - c.t_on <= 0.3 + 1e-3 and 3.0 <= s.duration <= 5.0
        assert 0.3 * s.duration < c.t_on < 0.7 * s.duration
    for s in _scripts(scripts.hold):
        (c,) = s.labels().contacts
        assert c.t_off - c.t_on >= 1.2 - 1e-3 and c.t_off < s.duration - 0.8
    for s in _scripts(scripts.swipe):
        (c,) = s.labels().contacts
        travel = np.hypot(*(c.path[-1, 1:] - c.path[0, 1:]))
        assert travel >= 40.0 - 1.0


def test_touch_height_is_zero_exactly_during_contact() -> None:
    s = scripts.tap(np.random.default_rng(3), TARGET, (0.0, 0.0), ROI)
    (c,) = s.labels().contacts
    for t in np.linspace(0, s.duration, 400):
        (pose,) = s.hand_poses(float(t))
        inside = c.t_on <= t < c.t_off
        assert (pose.tip_mm == 0.0) == inside
        if inside:
            x, y = c.position_at(float(t))
            assert math.hypot(pose.x - x, pose.y - y) < 0.5  # labels and the rendered fingertip agree


def test_hovers_never_touch_and_come_close() -> None:
    closest = []
    for s in _scripts(scripts.hover, 40):
        heights = [p.tip_mm for t in np.linspace(0, s.duration, 300) for p in s.hand_poses(float(t))]
        assert min(heights) >= HOVER_FLOOR_MM and s.labels().contacts == ()
        closest.append(min(heights))
    assert np.mean(np.array(closest) < 4.0) > 0.25  # many hovers come within a few mm


def test_tremor_is_between_8_and_12_hz() -> None:
    tremor = Tremor.draw(np.random.default_rng(4), drift_mm=0.0)
    track = HandTrack(keys=(Keyframe(0, 300, 200, 5.0),), tremor=tremor)
    fs = 200.0
    t = np.arange(0, 20, 1 / fs)
    h = np.array([track.fingertip(float(x))[2] for x in t])
    spectrum = np.abs(np.fft.rfft(h - h.mean()))
    freqs = np.fft.rfftfreq(len(h), 1 / fs)
    assert 8.0 <= freqs[np.argmax(spectrum)] <= 12.0
    assert 0.2 <= (h.max() - h.min()) / 2 <= 0.75


def test_disturbances_and_empties_have_no_contacts() -> None:
    for i, kind in enumerate(scripts.DISTURBANCE_KINDS * 3):
        s = scripts.disturbance(np.random.default_rng(i), kind, ROI)
        assert s.labels().contacts == () and s.label == "disturbance"
        for t in np.linspace(0, s.duration, 100):
            assert all(p.tip_mm >= 10.0 - 3.0 for p in s.hand_poses(float(t)) if p is not None)
    step = scripts.empty(np.random.default_rng(1), lighting_step=True)
    assert step.room(0.0) == 1.0 and step.room(step.duration) != 1.0
    with pytest.raises(ValueError, match="unknown disturbance"):
        scripts.disturbance(np.random.default_rng(0), "dance", ROI)


def test_continuous_clips() -> None:
    contact = scripts.contact_clip(np.random.default_rng(0), 75.0, ROI)
    covered = sum(c.t_off - c.t_on for c in contact.labels().contacts)
    assert covered > 0.7 * 75.0 and contact.labels().clip
    hover = scripts.hover_clip(np.random.default_rng(0), 75.0, ROI)
    heights = [p.tip_mm for t in np.arange(3, 72, 0.1) for p in hover.hand_poses(float(t))]
    assert min(heights) >= HOVER_FLOOR_MM and np.median(heights) < 15.0


def test_same_seed_same_frames_different_seed_different_frames() -> None:
    item = Item("s2/s2-tap-001", "s2-tap-001", "s2", "tap", 1)

    def first_frames(seed: int):
        script = build_script(item, seed)
        frames = render_frames(script, session_presets(seed)["s2"], recording_rng(seed, item.name, 1))
        return [next(frames) for _ in range(3)]

    a, b, c = first_frames(5), first_frames(5), first_frames(6)
    assert all(ta == tb and np.array_equal(fa, fb) for (ta, fa), (tb, fb) in zip(a, b))
    assert not np.array_equal(a[0][1], c[0][1])


def test_a_recording_does_not_depend_on_scale() -> None:
    small = {i.name: i for i in plan(0.1)}
    full = {i.name: i for i in plan(1.0)}
    name = "s1-hold-001"
    assert build_script(small[name], 9).labels().to_json() == build_script(full[name], 9).labels().to_json()
