"""End to end in sim: a static skin in a lit room, the projector lays the probe, a close hover does not fire, a tap does.

The projector service shows the default avatar (no wearer video: a static skin for touch) and lays the probe over
it (``[projector] probe = "auto"``), publishing each frame's level; the simulated rear camera's scene, in a lit
room (``[sim] room_light = 1``: the room's light through the membrane as bright as the projector's), is lit by
those levels after the projector's latency, as ``feelium run`` wires it (``light_scene_with_probe``). The touch
service mixes the same levels over each exposure and passes the probe's light, so the pipeline learns the
projector's share per place and its hover gate holds the close hover back. With the gate off
(``contact_projected_depth = 0``) the same hover fires: the test is the gate's, through the daemon's own parts.
"""

from __future__ import annotations

import asyncio
import dataclasses
import math

from feelium.cameras.select import CameraSource
from feelium.cameras.sim import SharedScene, SimRearCamera
from feelium.daemon.assembly import light_scene_with_probe
from feelium.events import TouchEvent
from feelium.hub import Hub
from feelium.interactions.config import InteractionsConfig
from feelium.projector.config import ProjectorConfig
from feelium.projector.display import SimDisplay
from feelium.projector.service import ProjectorService
from feelium.sim.config import SimConfig
from feelium.sim.live import LiveRearScene
from feelium.skin.projector_map import DEFAULT_CAMERA_SIZE, DEFAULT_ROI, default_calibration
from feelium.touch.config import TouchConfig
from feelium.touch.service import TouchService

SIZE = (320, 240)
LEARN_S = 2.5  # the probe's first periods: the share is learned (health says so) before anyone comes near
HOVER_S = 2.0
TAP_S = 1.5
HOVER_AT = (0.2, 0.25)  # a corner of the patch, where the back-light is dim and the room's share large
TAP_AT = (0.6, 0.55)


async def lit_room_run(touch_config: TouchConfig) -> tuple[list[TouchEvent], list[TouchEvent], dict, tuple]:
    hub = Hub()
    projector_cfg = ProjectorConfig()
    calibration = default_calibration(DEFAULT_CAMERA_SIZE, DEFAULT_ROI, (projector_cfg.width, projector_cfg.height))
    scene = LiveRearScene(SimConfig(autoplay=False, room_light=1.0), width=SIZE[0], height=SIZE[1])
    shared = SharedScene(scene, hub.clock)
    light_scene_with_probe(shared, hub, touch_config.projector_latency_s)
    touch = TouchService(
        CameraSource("sim", lambda: SimRearCamera(shared, fps=15.0), shared), hub, touch_config, debug_video_fps=0.0
    )
    projector = ProjectorService(
        projector_cfg, dataclasses.replace(InteractionsConfig(), enabled=False), hub, SimDisplay(), calibration
    )
    events = hub.bus.subscribe([TouchEvent], maxsize=256)
    rx, ry, rw, rh = scene.roi
    learned: dict = {}

    async def world() -> tuple[list[TouchEvent], list[TouchEvent]]:
        # The probe's first periods, counted in camera frames, not seconds: on a loaded machine the simulated camera
        # delivers fewer frames a second, and the share is learned from frames (LEARN_S at 15 fps at least).
        waited = hub.clock()
        while touch.probe_frames < LEARN_S * 15.0 and hub.clock() - waited < 6.0 * LEARN_S:
            await asyncio.sleep(0.1)
        learned.update(touch.health())
        start = hub.clock()
        shared.press(rx + rw * HOVER_AT[0], ry + rh * HOVER_AT[1], hub.clock(), hover=True)
        await asyncio.sleep(HOVER_S)
        shared.release(hub.clock())
        await asyncio.sleep(1.0)
        hovered = events.drain()
        shared.press(rx + rw * TAP_AT[0], ry + rh * TAP_AT[1], hub.clock())
        await asyncio.sleep(0.35)
        shared.release(hub.clock())
        await asyncio.sleep(TAP_S - 0.35)
        await touch.stop()
        await projector.stop()
        assert hub.clock() - start < HOVER_S + TAP_S + 3.0
        return hovered, events.drain()

    runs = [asyncio.create_task(touch.run()), asyncio.create_task(projector.run())]
    hovered, tapped = await world()
    await asyncio.gather(*runs)
    return hovered, tapped, learned, (rx + rw * TAP_AT[0], ry + rh * TAP_AT[1])


async def test_a_lit_rooms_close_hover_does_not_fire_and_a_tap_does() -> None:
    hovered, tapped, health, tap_at = await lit_room_run(TouchConfig())
    assert health["probe"] and health["probe_frames"] > 10, health
    assert health["light"]["share_learned"], health["light"]
    assert "not learned" not in health.get("reason", ""), health
    assert hovered == [], hovered
    downs = [e for e in tapped if e.phase == "down"]
    assert len(downs) == 1, tapped
    assert math.hypot(downs[0].x - tap_at[0], downs[0].y - tap_at[1]) <= 6.0


def test_the_probe_multiplies_compensated_content_on_the_contents_grid() -> None:
    """Content light over the ROI (the daemon predicts only there) takes the probe's cut of the same ROI; light over the
    whole frame the whole probe; light on any other grid is left as it is."""
    from types import SimpleNamespace

    import numpy as np

    from feelium.skin.probe import light_at, probe_pattern
    from feelium.touch.service import TouchService

    roi = (8, 4, 32, 24)
    over = SimpleNamespace(_pipeline=SimpleNamespace(roi=roi), _windowed=False)
    TouchService._probe_grids(over, (64, 48), roi)  # type: ignore[arg-type]
    probe = light_at(0.03, probe_pattern(64, 48))
    light = np.linspace(0.4, 0.6, 24 * 32, dtype=np.float32).reshape(24, 32)
    assert np.allclose(TouchService._probe_over(over, light, 0.03), light * probe[4:28, 8:40], atol=1e-6)  # type: ignore[arg-type]
    whole = np.full((48, 64), 0.5, np.float32)
    assert np.allclose(TouchService._probe_over(over, whole, 0.03), whole * probe, atol=1e-6)  # type: ignore[arg-type]
    odd = np.full((10, 10), 0.5, np.float32)
    assert TouchService._probe_over(over, odd, 0.03) is odd  # type: ignore[arg-type]
    assert over._probe_fine is None


def test_at_half_detection_scale_the_probe_reaches_the_detection_grid_and_the_fine_windows() -> None:
    """``detect_scale = 0.5``: the content's light comes on the detection grid and the fine pass's in windows of the
    working grid; the probe multiplies both, as the camera-size probe light averaged over each of their pixels."""
    from types import SimpleNamespace

    import cv2
    import numpy as np

    from feelium.skin.probe import light_at, probe_pattern
    from feelium.touch.pipeline import TouchPipeline
    from feelium.touch.service import TouchService

    size, level = (320, 240), -0.025
    pipeline = TouchPipeline(dataclasses.replace(TouchConfig(), width=320, height=240, detect_scale=0.5), size, None)
    grids = pipeline.light_grids
    assert grids is not None and grids.fine is not None
    window_light = np.full((20, 30), 0.8, np.float32)
    exposure = SimpleNamespace(window=lambda rows, cols: window_light.copy())
    svc = SimpleNamespace(_pipeline=pipeline, _windowed=True, _exposure_light=exposure, _probe_level=level)
    TouchService._probe_grids(svc, size, pipeline.roi)  # type: ignore[arg-type]
    camera = light_at(level, probe_pattern(*size))

    def on(grid: tuple[tuple[int, int], tuple[int, int, int, int]]) -> np.ndarray:
        (fw, fh), (x, y, w, h) = grid
        return cv2.resize(camera, (fw, fh), interpolation=cv2.INTER_AREA)[y : y + h, x : x + w]

    cw, ch = grids.coarse[1][2:]
    content = np.full((ch, cw), 0.7, np.float32)
    got = TouchService._probe_over(svc, content, level)  # type: ignore[arg-type]
    assert np.allclose(got, 0.7 * on(grids.coarse), atol=1e-6)
    assert got.std() > 0.005  # the cells are there, not averaged away
    rows, cols = slice(30, 50), slice(40, 70)
    window = TouchService._window_light(svc, rows, cols)  # type: ignore[arg-type]
    assert np.allclose(window, 0.8 * on(grids.fine)[rows, cols], atol=1e-6)
    svc._probe_level = None  # a frame without the probe: the content's light alone
    assert np.array_equal(TouchService._window_light(svc, rows, cols), window_light)  # type: ignore[arg-type]

