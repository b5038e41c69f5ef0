"""LiveRearScene: the sim daemon's rear camera and the partner page's press/hover/release."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.daemon.config import parse_config
from feelium.sim.config import SimConfig
from feelium.sim.live import LiveRearScene


def _spot(frame: np.ndarray, x: float, y: float, r: int = 4) -> float:
    return float(frame[int(y) - r : int(y) + r + 1, int(x) - r : int(x) + r + 1].mean())


@pytest.mark.parametrize("size", [(640, 480), (320, 240)])
def test_press_hover_release(size: tuple[int, int]) -> None:
    w, h = size
    scene = LiveRearScene(SimConfig(autoplay=False), width=w, height=h)
    assert scene.roi == (w // 10, h // 10, w * 4 // 5, h * 4 // 5)
    x, y = w * 0.4, h * 0.6
    empty = _spot(scene.frame(0.0), x, y)
    scene.press(x, y, 0.1)
    assert not scene.touching(0.12)  # still coming down
    frame = scene.frame(0.5)
    assert frame.shape == (h, w) and frame.dtype == np.uint8
    assert scene.touching(0.5) and _spot(frame, x, y) < 0.5 * empty
    scene.press(x + 20, y, 1.0)  # slide while pressed
    assert scene.touching(1.03) and scene.hand(1.5).x == pytest.approx(x + 20)
    scene.press(x, y, 2.0, hover=True)
    hover = [_spot(scene.frame(t), x, y) for t in np.arange(2.5, 4.0, 1 / 15)]
    assert not any(scene.touching(t) for t in np.arange(2.5, 4.0, 1 / 15))
    assert 0.25 * empty < np.mean(hover) < 0.9 * empty
    assert 2.0 <= min(scene.hand(t).tip_mm for t in np.arange(2.5, 4.0, 0.01)) <= 3.0  # wobbling near 3 mm
    scene.release(4.0)
    assert scene.hand(4.2) is not None and scene.hand(5.0) is None
    assert _spot(scene.frame(5.0), x, y) > 0.85 * empty


def test_autoplay_shows_activity_and_yields_to_a_person() -> None:
    scene = LiveRearScene(SimConfig(autoplay=True, autoplay_period_s=5.0, autoplay_idle_s=20.0))
    times = np.arange(0.0, 60.0, 1 / 15)
    touching = [scene.touching(t) for t in times]
    assert scene.autoplayed >= 4 and any(touching) and not all(touching)
    scene.press(300, 200, 60.0)
    scene.release(60.5)
    later = [scene.hand(t) for t in np.arange(61.5, 80.0, 1 / 15)]
    assert all(h is None for h in later)  # autoplay waits autoplay_idle_s after a person
    quiet = LiveRearScene(SimConfig(autoplay=False))
    assert not any(quiet.hand(t) for t in times) and quiet.autoplayed == 0


def test_same_config_same_frames() -> None:
    a, b = LiveRearScene(SimConfig(seed=4)), LiveRearScene(SimConfig(seed=4))
    for scene in (a, b):
        scene.press(200, 300, 0.0)
    assert all(np.array_equal(a.frame(t), b.frame(t)) for t in (0.3, 0.4))


def test_bad_input_is_refused_clearly() -> None:
    scene = LiveRearScene(SimConfig(autoplay=False))
    with pytest.raises(ValueError, match="finite"):
        scene.press(float("nan"), 1.0, 0.0)
    with pytest.raises(ValueError, match="finite"):
        scene.release(float("inf"))
    scene.release(0.0)  # releasing with no hand is harmless
    with pytest.raises(ValueError, match="at least"):
        LiveRearScene(SimConfig(), width=8, height=8)


def test_sim_config_section_parses() -> None:
    config = parse_config('[sim]\nseed = 3\nsession = "s2"\nautoplay = false\n')
    assert config.sim == SimConfig(seed=3, session="s2", autoplay=False)
    scene = LiveRearScene(config.sim)
    assert scene.session.name == "s2"
