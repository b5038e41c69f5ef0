"""The thermal channel of a simulated recording: the scene's hands and bodies as warm bodies.

The thermal camera looks at the sensitive patch, so a point at camera pixel
(x, y) is at ``u = (x - roi_x) / roi_w``, ``v = (y - roi_y) / roi_h`` on the
sensor. Each hand contributes its fingertip (at the fingertip's height) and its
palm (at the palm's height, the bulk of the hand's warmth); a passing body
contributes one large, cooler body (clothing). Sizes are radii as a fraction of
the patch width, as :class:`feelium.sim.thermal.WarmBody` expects. The
rendering itself is the thermal helper's :class:`ThermalSceneRenderer`.
"""

from __future__ import annotations

import math

import numpy as np

from feelium.recording import ThermalData
from feelium.sim.hand import HandPose
from feelium.sim.scene import SceneState
from feelium.sim.thermal import ThermalSceneRenderer, WarmBody

THERMAL_FPS = 8.0
FINGERTIP_RADIUS_MM = 8.0
PALM_RADIUS_MM = 45.0
PALM_ALONG_MM = 105.0  # palm centre behind the fingertip, measured in the membrane plane
CLOTHING_C = 29.0


def _uv(x: float, y: float, roi: tuple[int, int, int, int]) -> tuple[float, float]:
    rx, ry, rw, rh = roi
    return (x - rx) / rw, (y - ry) / rh


def hand_bodies(pose: HandPose, roi: tuple[int, int, int, int], px_per_mm: float) -> list[WarmBody]:
    """A hand's fingertip and palm as warm bodies."""
    patch_mm = roi[2] / px_per_mm
    u, v = _uv(pose.x, pose.y, roi)
    tip = WarmBody(u, v, pose.tip_mm, FINGERTIP_RADIUS_MM * pose.size / patch_mm)
    pitch = math.radians(pose.pitch_deg)
    along = PALM_ALONG_MM * math.cos(pitch) * pose.size * px_per_mm
    px, py = pose.x + math.cos(pose.heading) * along, pose.y + math.sin(pose.heading) * along
    palm_h = pose.tip_mm + 80.0 * math.sin(pitch) + 15.0
    pu, pv = _uv(px, py, roi)
    palm = WarmBody(pu, pv, palm_h, PALM_RADIUS_MM * pose.size / patch_mm)
    return [tip, palm]


def warm_bodies(state: SceneState, roi: tuple[int, int, int, int], px_per_mm: float) -> list[WarmBody]:
    """Everything warm outside the membrane at one instant."""
    bodies: list[WarmBody] = []
    for hand in state.hands:
        bodies += hand_bodies(hand, roi, px_per_mm)
    for blob in state.blobs:
        u, v = _uv(blob.x, blob.y, roi)
        bodies.append(WarmBody(u, v, blob.height_mm, max(blob.radius_x, blob.radius_y) / roi[2], CLOTHING_C))
    return bodies


def thermal_times(duration_s: float, rng: np.random.Generator, fps: float = THERMAL_FPS) -> np.ndarray:
    """Sub-page times at ``fps`` with a random start phase and 1 ms of jitter; strictly increasing."""
    period = 1.0 / fps
    start = float(rng.uniform(0.0, period))
    slots = start + np.arange(int(math.floor((duration_s - start) * fps)), dtype=np.float64) * period
    return slots + np.clip(rng.normal(0.0, 1e-3, len(slots)), -0.2 * period, 0.2 * period)


def render_thermal(
    state_at, duration_s: float, roi: tuple[int, int, int, int], px_per_mm: float, ambient_c: float, rng: np.random.Generator
) -> ThermalData:
    """Thermal frames over a recording: ``state_at(t)`` gives the scene (a script's ``state``)."""
    renderer = ThermalSceneRenderer(rng, ambient_c)
    times = thermal_times(duration_s, rng)
    frames = [renderer.frame(float(t), warm_bodies(state_at(float(t)), roi, px_per_mm)) for t in times]
    celsius = np.stack(frames).astype(np.float32) if frames else np.zeros((0, 24, 32), np.float32)
    return ThermalData(t=times, celsius=celsius)
