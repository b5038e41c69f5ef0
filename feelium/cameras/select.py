"""Which camera backend to run, from the config: ``auto`` picks hardware when it is there, else the simulator."""

from __future__ import annotations

import importlib
import logging
from collections.abc import Callable
from dataclasses import dataclass, replace
from types import ModuleType
from typing import TYPE_CHECKING

from feelium.cameras.base import Camera, CameraUnavailable
from feelium.cameras.lens import FisheyeLens, LensError, load_lens
from feelium.cameras.picamera2_backend import camera_count, hardware_jpeg_available, load_picamera2

if TYPE_CHECKING:
    from feelium.cameras.config import FrontCameraConfig, RearCameraConfig
    from feelium.cameras.sim import SharedScene
    from feelium.sim.config import SimConfig

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CameraSource:
    """A chosen backend: its name, how to open it (again after a crash), the sim scene and the lens if known."""

    backend: str
    open: Callable[[], Camera]
    scene: "SharedScene | None" = None
    lens: FisheyeLens | None = None


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
            "replay",
            lambda: ReplayCamera(
                cfg.replay_path, realtime=cfg.replay_realtime, loop=cfg.replay_loop,
                projector_stream=cfg.projection_compensation != "off", calibration=cfg.replay_projector_calibration or None,
            ),  # fmt: skip
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


def front_lens(cfg: "FrontCameraConfig", backend: str, config_file: str | None = None) -> FisheyeLens:
    """The lens model of the front frames: the simulator's own, else the calibrated file, else a nominal stand-in.

    A lens file that cannot be read or does not fit the frame size is logged and replaced by the stand-in
    (``source: "nominal"`` tells the headset) rather than stopping the wearer's video over marker placement.
    """
    from feelium.cameras.sim_front import sim_lens
    from feelium.skin.projector_map import calibration_path

    if backend == "sim":
        return sim_lens(cfg.width, cfg.height)
    path = calibration_path(cfg.lens_file, config_file)
    if path.exists():
        try:
            return load_lens(path).scaled(cfg.width, cfg.height)
        except LensError as exc:
            log.error("front camera: %s; serving the uncalibrated 180-degree lens instead", exc)
    else:
        log.warning("front camera: no lens file %s (feelium calibrate lens); serving an uncalibrated 180-degree lens", path)
    return replace(sim_lens(cfg.width, cfg.height), source="nominal")


def front_camera_source(cfg: "FrontCameraConfig", sim_seed: int) -> CameraSource | None:
    """How to open the front (fisheye) camera, or ``None`` when it is off."""
    backend, device = resolve_front_backend(cfg)
    if backend == "off":
        return None
    lens = front_lens(cfg, backend)
    if backend == "sim":
        from feelium.cameras.sim import SimFrontCamera

        return CameraSource("sim", lambda: SimFrontCamera(cfg.width, cfg.height, cfg.fps, seed=sim_seed), lens=lens)
    if backend == "v4l2":
        from feelium.cameras.v4l2 import V4l2Camera

        return CameraSource("v4l2", lambda: V4l2Camera(device, cfg.width, cfg.height, cfg.fps, jpeg=cfg.jpeg), lens=lens)
    if backend == "replay":
        from feelium.cameras.replay import ReplayCamera

        return CameraSource("replay", lambda: ReplayCamera(cfg.replay_path, realtime=True, loop=True, gray=False), lens=lens)
    from feelium.cameras.picamera2_backend import Picamera2FrontCamera

    return CameraSource(
        "picamera2",
        lambda: Picamera2FrontCamera(
            index=cfg.camera_index, width=cfg.width, height=cfg.height, fps=cfg.fps, jpeg=front_jpeg_encoder(cfg)
        ),
        lens=lens,
    )


def front_jpeg_encoder(cfg: "FrontCameraConfig", module: ModuleType | None = None) -> str:
    """``hardware`` or ``software``: who encodes the picamera2 front camera's JPEGs (``auto`` asks picamera2)."""
    if cfg.jpeg != "auto":
        return cfg.jpeg
    found = hardware_jpeg_available(module if module is not None else load_picamera2())
    if not found:
        log.info("front camera: picamera2 offers no hardware JPEG encoder here; the daemon encodes in software")
    return "hardware" if found else "software"
