"""Which camera backend to run, from the config: ``auto`` picks hardware when it is there, else the simulator."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from feelium.cameras.base import Camera, CameraUnavailable
from feelium.cameras.picamera2_backend import camera_count

if TYPE_CHECKING:
    from feelium.cameras.config import FrontCameraConfig, RearCameraConfig
    from feelium.cameras.sim import SharedScene
    from feelium.sim.config import SimConfig


@dataclass(frozen=True)
class CameraSource:
    """A chosen backend: its name, how to open it (again after a crash), and the sim scene if any."""

    backend: str
    open: Callable[[], Camera]
    scene: "SharedScene | None" = None


def resolve_rear_backend(cfg: "RearCameraConfig") -> str:
    if cfg.backend == "auto":
        return "picamera2" if camera_count() > cfg.camera_index else "sim"
    return cfg.backend


def resolve_front_backend(cfg: "FrontCameraConfig") -> tuple[str, str]:
    """The front backend and, for v4l2, the device to open."""
    from feelium.cameras.v4l2 import usb_camera_devices

    if cfg.backend != "auto":
        return cfg.backend, cfg.device
    if camera_count() > cfg.camera_index:
        return "picamera2", cfg.device
    devices = usb_camera_devices()
    if devices:
        return "v4l2", devices[0]
    return "sim", cfg.device


def live_rear_scene(sim: "SimConfig", work_size: tuple[int, int], clock: Callable[[], float]) -> "SharedScene":
    """The scene simulator's live scene at the touch pipeline's working resolution."""
    from feelium.cameras.sim import SharedScene

    try:
        live = importlib.import_module("feelium.sim.live")
    except ImportError as exc:
        raise CameraUnavailable(f"the scene simulator is not available ({exc}); use rear_camera.backend = 'replay'") from exc
    scene = live.LiveRearScene(sim, width=work_size[0], height=work_size[1])
    return SharedScene(scene, clock)


def rear_camera_source(
    cfg: "RearCameraConfig", work_size: tuple[int, int], sim: "SimConfig", clock: Callable[[], float]
) -> CameraSource | None:
    """How to open the rear (touch) camera, or ``None`` when it is off.

    ``work_size`` is the touch pipeline's working frame size (``[touch] width x height``):
    the camera delivers frames at that size, so the pipeline never resizes whole frames.
    """
    backend = resolve_rear_backend(cfg)
    if backend == "off":
        return None
    if backend == "sim":
        from feelium.cameras.sim import SimRearCamera

        scene = live_rear_scene(sim, work_size, clock)
        return CameraSource("sim", lambda: SimRearCamera(scene, cfg.fps), scene)
    if backend == "replay":
        from feelium.cameras.replay import ReplayCamera

        return CameraSource(
            "replay", lambda: ReplayCamera(cfg.replay_path, realtime=cfg.replay_realtime, loop=cfg.replay_loop)
        )
    from feelium.cameras.base import Roi
    from feelium.cameras.config import check_roi
    from feelium.cameras.picamera2_backend import Picamera2RearCamera

    width, height = work_size
    check_roi(cfg.roi, width, height, "rear_camera.roi")
    roi: Roi | None = tuple(cfg.roi) if cfg.roi else None  # type: ignore[assignment]
    return CameraSource(
        "picamera2",
        lambda: Picamera2RearCamera(
            index=cfg.camera_index, width=width, height=height, fps=cfg.fps, settle_s=cfg.settle_s, roi=roi
        ),
    )


def front_camera_source(cfg: "FrontCameraConfig", sim_seed: int) -> CameraSource | None:
    """How to open the front (fisheye) camera, or ``None`` when it is off."""
    backend, device = resolve_front_backend(cfg)
    if backend == "off":
        return None
    if backend == "sim":
        from feelium.cameras.sim import SimFrontCamera

        return CameraSource("sim", lambda: SimFrontCamera(cfg.width, cfg.height, cfg.fps, seed=sim_seed))
    if backend == "v4l2":
        from feelium.cameras.v4l2 import V4l2Camera

        return CameraSource("v4l2", lambda: V4l2Camera(device, cfg.width, cfg.height, cfg.fps))
    if backend == "replay":
        from feelium.cameras.replay import ReplayCamera

        return CameraSource("replay", lambda: ReplayCamera(cfg.replay_path, realtime=True, loop=True, gray=False))
    from feelium.cameras.picamera2_backend import Picamera2FrontCamera

    return CameraSource(
        "picamera2", lambda: Picamera2FrontCamera(index=cfg.camera_index, width=cfg.width, height=cfg.height, fps=cfg.fps)
    )
