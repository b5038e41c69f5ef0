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
        start = hub.clock()
        await asyncio.sleep(LEARN_S)
        learned.update(touch.health())
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
        assert hub.clock() - start < LEARN_S + HOVER_S + TAP_S + 3.0
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
    """Content light over the ROI (the daemon predicts only there) takes the probe's cut of the same ROI; light on a
    coarser detection grid is left as it is (docs/touch.md); equal grids multiply."""
    from types import SimpleNamespace

    import numpy as np

    from feelium.touch.service import TouchService

    probe = np.linspace(0.97, 1.03, 48 * 64, dtype=np.float32).reshape(48, 64)
    roi = (8, 4, 32, 24)
    over = SimpleNamespace(_pipeline=SimpleNamespace(roi=roi), _windowed=False)
    light = np.full((24, 32), 0.5, np.float32)
    got = TouchService._probe_over(over, light, probe)  # type: ignore[arg-type]
    assert np.array_equal(got, light * probe[4:28, 8:40])
    whole = np.full((48, 64), 0.5, np.float32)
    assert np.array_equal(TouchService._probe_over(over, whole, probe), whole * probe)  # type: ignore[arg-type]
    coarse = SimpleNamespace(_pipeline=SimpleNamespace(roi=roi), _windowed=True)
    small = np.full((12, 16), 0.5, np.float32)
    assert TouchService._probe_over(coarse, small, probe) is small  # type: ignore[arg-type]
