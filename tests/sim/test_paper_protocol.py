"""End to end: ``feelium simulate paper-protocol --scale`` writes a readable, correctly labelled dataset."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest

from feelium.cli import main
from feelium.recording import TOUCH_LABELS, Recording, find_recordings
from feelium.lab.sim.protocol import TRIAL_COUNTS, class_counts, plan


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("protocol")
    assert main(["simulate", "paper-protocol", "--out", str(out), "--seed", "3", "--scale", "0.02", "--jobs", "2", "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def recordings(dataset: Path) -> list[tuple[Recording, list[tuple[float, np.ndarray]]]]:
    """Every recording read back once, with its decoded frames."""
    loaded = []
    for path in find_recordings(dataset):
        rec = Recording(path)
        loaded.append((rec, list(rec.frames())))
    return loaded


def test_full_plan_matches_the_paper() -> None:
    items = plan(1.0)
    trials = Counter(i.label for i in items if not i.clip)
    assert dict(trials) == TRIAL_COUNTS and sum(trials.values()) == 228
    assert sorted(i.label for i in items if i.clip) == ["contact", "empty", "hover"]
    assert all(i.clip_seconds == 75.0 for i in items if i.clip)
    sessions = Counter(i.session for i in items if not i.clip)
    assert set(sessions) == {"s1", "s2", "s3"} and max(sessions.values()) - min(sessions.values()) <= 2


def test_scale_keeps_at_least_one_of_each() -> None:
    assert all(n >= 1 for n in class_counts(0.001).values())
    with pytest.raises(ValueError):
        class_counts(0.0)


def test_counts_by_label(recordings) -> None:
    trials = Counter(r.labels.label for r, _ in recordings if not r.labels.clip)
    assert dict(trials) == class_counts(0.02)
    clips = sorted(r.labels.label for r, _ in recordings if r.labels.clip)
    assert clips == ["contact", "empty", "hover"]


def test_meta_and_labels_follow_the_format(recordings) -> None:
    for rec, _ in recordings:
        meta = json.loads((rec.path / "meta.json").read_text())
        assert meta["source"] == "synthetic" and meta["roi"] == [64, 48, 512, 384]
        assert meta["camera"]["width"] == 640 and meta["camera"]["height"] == 480 and meta["camera"]["fps"] == 15.0
        assert meta["generator"]["seed"] == 3 and meta["generator"]["session"]["name"] == rec.meta.session
        labels = rec.labels
        assert labels is not None
        ts = rec.timestamps
        assert ts[0] < 0.1 and np.all(np.diff(ts) > 0)
        if labels.label in TOUCH_LABELS:
            assert labels.target is not None and len(labels.contacts) == 1
        if labels.label in ("hover", "disturbance", "empty"):
            assert labels.contacts == ()
        for c in labels.contacts:
            assert 0.0 < c.t_on < c.t_off < ts[-1]
            assert c.path is not None and c.path[0, 0] == pytest.approx(c.t_on, abs=1e-3)
            assert np.all((c.path[:, 0] >= c.t_on) & (c.path[:, 0] <= c.t_off))


def _patch_mean(frame: np.ndarray, x: float, y: float, r: int = 4) -> float:
    xi, yi = int(round(x)), int(round(y))
    return float(frame[yi - r : yi + r + 1, xi - r : xi + r + 1].mean())


def test_labelled_contacts_are_dark_in_the_frames(recordings) -> None:
    """Labels match frames: under the labelled fingertip the membrane is much darker while touching."""
    checked = 0
    for rec, frames in recordings:
        if not rec.labels.contacts:
            continue
        first = frames[0][1]
        for c in rec.labels.contacts:
            inside = [(t, f) for t, f in frames if c.t_on + 0.05 <= t < c.t_off - 0.03]
            for t, frame in inside[:5]:
                x, y = c.position_at(t)
                ratio = _patch_mean(frame, x, y) / max(_patch_mean(first, x, y), 1.0)
                assert ratio < 0.5, f"{rec.name} t={t:.2f}: contact at ({x:.0f},{y:.0f}) only {ratio:.2f} of empty"
                checked += 1
    assert checked >= 3


def test_empty_trials_have_no_hand(recordings) -> None:
    """An empty scene changes only globally: no local dark spot anywhere in the ROI."""
    for rec, decoded in recordings:
        if rec.labels.label != "empty":
            continue
        frames = [f.astype(np.float32) for _, f in decoded]
        x, y, w, h = rec.meta.roi
        ref = frames[0][y : y + h, x : x + w]
        for f in frames[1:]:
            ratio = f[y : y + h, x : x + w] / np.maximum(ref, 1.0)
            # a global step is allowed; a local shadow is not: the ratio is spatially flat up to noise
            smooth = np.median(ratio)
            blurred = cv2.blur(ratio, (15, 15))
            assert np.abs(blurred - smooth).max() < 0.25 * max(smooth, 0.2)


def test_every_recording_has_a_thermal_channel_that_sees_the_hand(recordings) -> None:
    warm_touch = 0
    for rec, frames in recordings:
        thermal = rec.thermal()
        assert thermal is not None and rec.meta.thermal == {"width": 32, "height": 24, "fps": 8.0}
        assert np.all(np.diff(thermal.t) > 0) and thermal.t[-1] <= rec.timestamps[-1] + 0.2
        assert len(thermal.t) == pytest.approx(8.0 * (rec.timestamps[-1] - rec.timestamps[0]), abs=3)
        ambient = float(np.median(thermal.celsius[0]))
        if rec.labels.label == "empty":
            assert np.abs(thermal.celsius - ambient).max() < 2.0
        for c in rec.labels.contacts:
            during = thermal.celsius[(thermal.t >= c.t_on) & (thermal.t < c.t_off)]
            if len(during):
                assert during.max() > ambient + 2.0
                warm_touch += 1
    assert warm_touch >= 2
