"""The probe laid over projector frames, and its level mixed over a camera exposure."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.projector.canvaslight import light_table
from feelium.projector.config import ProjectorConfig
from feelium.projector.probe import ProbeOverlay
from feelium.skin.probe import AMPLITUDE, ProbeLevels, cell_for, probe_pattern
from feelium.skin.projector_map import DEFAULT_CAMERA_SIZE, DEFAULT_ROI, default_calibration


@pytest.fixture(scope="module")
def overlay() -> tuple[ProbeOverlay, ProjectorConfig]:
    config = ProjectorConfig()
    calibration = default_calibration(DEFAULT_CAMERA_SIZE, DEFAULT_ROI, (config.width, config.height))
    return ProbeOverlay(config, calibration), config


def test_the_pattern_keeps_its_cells_on_the_skin_at_any_camera_resolution() -> None:
    assert cell_for(640) == 64 and cell_for(320) == 32
    full, half = probe_pattern(640, 480), probe_pattern(320, 240)
    assert np.array_equal(full[::2, ::2], half)
    assert abs(float(full.mean())) < 0.05  # as much brightens as dims: the mean does not move


def test_the_probe_brightens_half_the_seen_skin_and_dims_the_other_half_by_the_level_told(overlay) -> None:
    probe, config = overlay
    flat = int(round(config.flat_level * 255))
    frame = np.full((config.height, config.width, 3), flat, np.uint8)
    frame[:8] = 0  # black stays black
    out, level = probe.lay(frame, AMPLITUDE)
    assert out is not frame and np.all(frame == np.where(frame == 0, 0, flat))  # the shown frame is not written
    assert np.all(out[:8] == 0)
    light = light_table(config, default_calibration(DEFAULT_CAMERA_SIZE, DEFAULT_ROI, (config.width, config.height)))
    values, counts = np.unique(out[8:], return_counts=True)
    up, down = light[values.max()] / light[flat] - 1.0, 1.0 - light[values.min()] / light[flat]
    assert level == pytest.approx((up + down) / 2.0, rel=1e-5)
    assert abs(level - AMPLITUDE) <= 0.5 * (light[flat + 1] / light[flat] - 1.0)  # within half a grey step
    n_up, n_down = counts[values == values.max()][0], counts[values == values.min()][0]
    assert 0.8 < n_up / n_down < 1.25
    _, none = probe.lay(frame, 0.0)
    assert none == 0.0


def test_the_level_is_mixed_over_the_exposure_after_the_latency() -> None:
    levels = ProbeLevels(window_s=1.0)
    assert levels.level(0.0, 0.03, 0.03) is None and not levels.active()
    for i, level in enumerate([0.01, 0.02, None]):
        levels.record(i * 0.1, level)
    assert not levels.active()  # the newest frame carries no probe
    # exposure [0.07, 0.13] - latency 0.03 = [0.04, 0.10]: all frame 0's light
    assert levels.level(0.10, 0.06, 0.03) == pytest.approx(0.01)
    # [0.07, 0.13]: half frame 0, half frame 1
    assert levels.level(0.13, 0.06, 0.03) == pytest.approx(0.015)
    assert levels.level(0.30, 0.0, 0.03) == 0.0  # frame 2: none
    levels.record(0.15, 0.5)  # out of order: ignored
    assert levels.level(0.13, 0.06, 0.03) == pytest.approx(0.015)


@settings(max_examples=40, deadline=None)
@given(st.floats(-0.05, 0.05), st.floats(0.0, 0.1), st.floats(0.0, 0.2))
def test_a_constant_level_is_its_own_mix(level: float, exposure: float, t: float) -> None:
    levels = ProbeLevels(window_s=1.0)
    for i in range(6):
        levels.record(i * 1 / 30, level)
    assert levels.level(t, exposure, 0.033) == pytest.approx(level, abs=1e-12)
