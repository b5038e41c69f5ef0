"""`feelium calibrate projector RECORDING` measures the projector's latency from the recording itself.

The recordings come from the simulator's projector on its own clock (:mod:`feelium.lab.sim.take_calibration`):
its light reaches the membrane a true latency after the frame clock and the camera integrates it over its
exposure, so a frame straddling a switch mixes two patterns. The config assumes 33 ms; the truths differ.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from feelium.cli import main
from feelium.daemon.config import Config
from feelium.lab.projector.from_recording import recording_latency
from feelium.lab.projector.latency import LatencyError
from feelium.touch.projected import touch_with_latency
from feelium.lab.sim.take_calibration import write_latency_take
from feelium.recording import Recording
from feelium.skin.projector_map import default_calibration, load_calibration
from feelium.touch.config import TouchConfig

CONFIG = Config()
SIZE = (CONFIG.projector.width, CONFIG.projector.height)
ASSUMED = CONFIG.touch.projector_latency_s  # 33 ms


def _stripes(pairs: int = 10) -> list[np.ndarray]:
    """Vertical binary stripes, coarsest first, each followed by its inverse (the generic decoder's sequence)."""
    w, h = SIZE
    out = []
    for bit in range(1, pairs + 1):
        row = ((np.arange(w) * 2**bit) // w % 2 * 255).astype(np.uint8)
        pattern = np.repeat(row[None, :], h, axis=0)
        out += [pattern, 255 - pattern]
    return out


@pytest.mark.parametrize("true_s", [0.080, 0.020])
def test_the_latency_is_measured_within_5_ms_and_kept_in_the_map(tmp_path, capsys, true_s):
    assert abs(true_s - ASSUMED) > 0.01  # the truth is not the assumption
    path = write_latency_take(tmp_path / "calibration", _stripes(), true_s, seed=1)
    config = tmp_path / "feelium.toml"
    config.write_text("[projector.calibration]\nsettle_frames = 0\nframes_per_pattern = 1\n")
    out = tmp_path / "map.npz"
    assert main(["calibrate", "projector", str(path), "--config", str(config), "--out", str(out), "--json"]) == 0
    latency = json.loads(capsys.readouterr().out)["latency"]
    assert latency["measured"] and latency["exposure_from"] == "recording meta"
    assert latency["latency_ms"] == pytest.approx(true_s * 1e3, abs=5.0)
    assert latency["straddling_frames"] >= 3 and latency["uncertainty_ms"] < 5.0
    assert latency["touch_keys"]["projector_latency_s"] == pytest.approx(true_s, abs=0.005)
    assert latency["touch_keys"]["projector_latency_sigma_s"] >= CONFIG.touch.projector_latency_sigma_s
    saved = load_calibration(out)
    assert saved.latency_s == pytest.approx(true_s, abs=0.005) and saved.latency_sigma_s is not None


def test_without_the_meta_exposure_the_configs_is_used(tmp_path):
    path = write_latency_take(tmp_path / "calibration", _stripes(), 0.080, seed=2)
    meta = json.loads((path / "meta.json").read_text())
    del meta["camera"]["exposure_s"]
    (path / "meta.json").write_text(json.dumps(meta))
    estimate = recording_latency(Recording(path), CONFIG.touch.camera_exposure_s)  # the simulated sensor's 30 ms too
    assert estimate.exposure_from == "config" and estimate.latency_s == pytest.approx(0.080, abs=0.005)


def test_a_latency_of_several_patterns_is_found_not_aliased(tmp_path):
    """350 ms: over two patterns late. Searched only to 300 ms this came out as 185 ms (free per-pattern images fit a
    latency a few patterns off too, only worse); the whole range finds it."""
    path = write_latency_take(tmp_path / "slow", _stripes(), 0.350, seed=1)
    assert recording_latency(Recording(path), CONFIG.touch.camera_exposure_s).latency_s == pytest.approx(0.350, abs=0.005)


def test_a_sequence_without_switches_is_refused_not_guessed(tmp_path):
    white = np.full(SIZE[::-1], 255, np.uint8)
    path = write_latency_take(tmp_path / "still", [white, white.copy()], 0.080)  # one pattern, held
    with pytest.raises(LatencyError, match="0 pattern switch"):
        recording_latency(Recording(path), CONFIG.touch.camera_exposure_s)


def test_patterns_too_short_to_be_seen_alone_are_refused_not_guessed(tmp_path):
    """Each pattern held 3-6 refreshes of 60 Hz (50-100 ms, at most a 15 fps camera's frame and a half): too few
    patterns are seen alone for a share to be checked against its two patterns; a refusal, not a latency."""
    path = write_latency_take(tmp_path / "short", _stripes(), 0.080, hold=3)
    with pytest.raises(LatencyError, match="too few to tell"):
        recording_latency(Recording(path), CONFIG.touch.camera_exposure_s)


def test_the_measured_spread_only_widens_the_configured_one():
    cal = default_calibration((64, 48), None, (128, 72))
    touch = TouchConfig()
    assert touch_with_latency(touch, cal) is touch  # nothing measured: the config's
    narrow = touch_with_latency(touch, dataclasses.replace(cal, latency_s=0.08, latency_sigma_s=0.001))
    assert narrow.projector_latency_s == 0.08 and narrow.projector_latency_sigma_s == touch.projector_latency_sigma_s
    wide = touch_with_latency(touch, dataclasses.replace(cal, latency_s=0.08, latency_sigma_s=0.03))
    assert wide.projector_latency_sigma_s == 0.03
