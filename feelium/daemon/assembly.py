"""The running daemon, assembled in one place, in the order data flows.

Read this file to know every part that runs and what feeds what::

    rear camera --frames--> touch --TouchEvent--> bus --> projector (interactions, answers on the skin)
    front camera --frames--> hub.front_video                  --> http (events, video) --> headset
    thermal camera --frames--> thermal (presence) --PresenceEvent--> bus
    microphone --SpeechOut--> bus --> http;   http --SpeechIn--> bus --> audio (speaker)
    headset --http--> hub.motion (dead man) --> flight --MSP--> motor board

Each ``build_*`` function builds the backend the config names (``auto`` is
already resolved by ``feelium.daemon.backends``: the hardware on a Raspberry
Pi, the simulated part elsewhere) and returns the service, or ``None`` when
the config switches the part off. Services meet only in the
:class:`~feelium.hub.Hub`; the wiring between parts that must share
something (the projector calibration the touch service annotates with)
happens here, so no service imports another. Adding a service is one line in
:data:`SERVICES`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from feelium.cameras.select import CameraSource, front_camera_source, rear_camera_source
from feelium.daemon.config import Config
from feelium.hub import Hub
from feelium.service import Service
from feelium.settings import ConfigError
from feelium.skin.annotation import ProjectorAnnotation
from feelium.skin.projector_map import CalibrationError, calibration_path, default_calibration, load_or_default, load_shared
from feelium.skin.projector_map import DEFAULT_CAMERA_SIZE, DEFAULT_ROI
from feelium.skin.regions import Regions

if TYPE_CHECKING:
    from feelium.cameras.base import ProjectorStream
    from feelium.projector.display import Display
    from feelium.projector.showloop import ShowLoop
    from feelium.touch.config import TouchConfig

log = logging.getLogger(__name__)

ServiceBuilder = Callable[[Config, Hub], "Service | None"]
ProjectedFactory = Callable[..., Callable[[np.ndarray, np.ndarray | None], np.ndarray]]  # feelium.touch.service
# A replayed recording's projector stream -> its light's predictor and the touch config its exposures are mixed with.
StreamLightFactory = Callable[["ProjectorStream"], "tuple[ProjectedFactory, TouchConfig]"]


# --- sensing: cameras and the thermal camera feed the bus -------------------------------------------------------


def rear_camera(config: Config, clock: Callable[[], float]) -> CameraSource | None:
    """The rear (touch) camera the config asks for, at the touch pipeline's working size; ``None`` when off."""
    return rear_camera_source(config.rear_camera, (config.touch.width, config.touch.height), config.sim, clock)


def build_touch(config: Config, hub: Hub) -> Service | None:
    """Rear camera -> touch pipeline -> ``TouchEvent`` on the bus (annotated with the skin when calibrated)."""
    from feelium.touch.service import TouchService

    source = rear_camera(config, hub.clock)
    if source is None:
        return None
    hub.rear_scene = source.scene  # the simulated scene, for the partner page's presses; None on hardware
    touch = touch_config_with_measured_latency(config)
    if source.scene is not None:
        light_scene_with_probe(source.scene, hub, touch.projector_latency_s)
    replayed = source.backend == "replay"  # lit by what the recording's projector showed, not by this one
    return TouchService(
        source,
        hub,
        touch,
        debug_video_fps=config.rear_camera.debug_video_fps,
        annotation=load_projector_annotation(config),
        projected=None if replayed else load_projected_light(config, source.backend),
        stream_light=replay_stream_light(config, config.touch) if replayed else None,
        stale_after_s=config.rear_camera.stale_after_s,
    )


def replay_stream_light(config: Config, touch: TouchConfig) -> StreamLightFactory | None:
    """How touch predicts the light of a replayed recording's projector stream, or ``None`` when compensation is off.

    The frames were lit by the projector of the recording, so touch predicts from its recorded frames through its
    map (a saved map beside it, or ``[rear_camera] replay_projector_calibration``), exactly as ``feelium replay`` and
    ``eval`` do (:mod:`feelium.projector.recorded`), with the latency the map measured when it did. The map is
    loaded per recording when its first frame comes; one that is missing or unusable is an error the touch service
    reports in health and replays that recording uncompensated. A calibration *recording* beside it is not fitted
    here (the daemon does not load lab code): ``feelium run --replay`` fits it before the daemon starts and passes
    the map as ``replay_projector_calibration`` (``feelium.cli.daemon``)."""
    if config.rear_camera.projection_compensation == "off":
        return None

    def for_stream(stream: ProjectorStream) -> tuple[ProjectedFactory, TouchConfig]:
        from feelium.projector.recorded import stream_light, stream_optics
        from feelium.recording import Recording
        from feelium.skin.projector_map import load_calibration
        from feelium.touch.projected import touch_with_latency

        path = stream.calibration
        if path is None:
            raise ValueError(
                f"{stream.recording} has a projector stream but no projector calibration beside it "
                "(projector-calibration.npz) and none was given (--projector-calibration)"
            )
        if path.is_dir():
            raise ValueError(
                f"the projector calibration of {stream.recording} is a calibration recording ({path}), which the daemon "
                "does not fit: `feelium calibrate projector` fits and saves its map; pass it with --projector-calibration"
            )
        calibration = load_calibration(path)
        optics = stream_optics(config.projector, Recording(stream.recording), calibration, path)
        return stream_light(optics, calibration), touch_with_latency(touch, calibration)

    return for_stream


def touch_config_with_measured_latency(config: Config) -> TouchConfig:
    """``[touch]`` with the projector's latency that ``feelium calibrate projector`` measured from a calibration
    recording and saved with the map (``[projector.calibration] file``), when it did: the blimp's own projector's
    latency, not the assumed 33 ms (50-100 ms more than assumed turned a face's cut edges into contact edges:
    docs/touch.md, *A hostile review before closing issue 17*). Without a file or a measurement, ``[touch]`` as it
    is; a file that does not load is the projector's and touch's to report (they read it too)."""
    from feelium.touch.projected import touch_with_latency

    path = calibration_path(config.projector.calibration.file)
    if not path.exists():
        return config.touch
    try:
        calibration = load_shared(path)
    except Exception:  # noqa: BLE001 - reported where the map is used (the projector's build, the compensation)
        return config.touch
    touch = touch_with_latency(config.touch, calibration)
    if touch is not config.touch:
        log.info(
            "touch: projector latency %.1f ms (sigma %.1f ms), measured with the calibration %s ([touch] says %.1f ms)",
            1e3 * touch.projector_latency_s, 1e3 * touch.projector_latency_sigma_s, path, 1e3 * config.touch.projector_latency_s,
        )
    return touch


def light_scene_with_probe(scene: Any, hub: Hub, latency_s: float) -> None:
    """The simulated rear scene sees the probe the projector service lays (``hub.projector_probe``), ``latency_s``
    after each frame was shown (the latency touch assumes: the simulated projector has no other), so ``feelium
    run`` in sim exercises the probe from the projector's frames to the touch pipeline's share."""
    from feelium.skin.probe import ProbeLevels

    levels = ProbeLevels()
    hub.projector_probe.listen(lambda item: levels.record(item.t, item.value))
    scene.project_probe(levels, latency_s)


def build_front_camera(config: Config, hub: Hub) -> Service | None:
    """Fisheye -> ``hub.front_video`` (what the wearer sees)."""
    from feelium.front_camera.service import FrontCameraService

    source = front_camera_source(config.front_camera, config.sim.seed)
    if source is None:
        return None
    if source.lens is not None:  # for the headset: GET /lens, with where the skin is in the view
        skin = [config.touch.face_azimuth_deg, config.touch.face_elevation_deg]
        hub.front_lens = source.lens.to_json() | {"skin_patch_deg": skin}
    else:
        hub.front_lens = None
    return FrontCameraService(source, hub)


def build_thermal(config: Config, hub: Hub) -> Service | None:
    """MLX90640 (or its I2C-level simulation) -> presence detector -> ``PresenceEvent`` on the bus."""
    from feelium.thermal.service import ThermalService, choose_backend, sim_driver, smbus2_driver

    cfg = config.thermal
    if cfg.backend == "off":
        return None
    if choose_backend(cfg) == "smbus2":
        return ThermalService(cfg, hub, lambda: smbus2_driver(cfg), "smbus2")
    seed = config.sim.seed
    return ThermalService(cfg, hub, lambda: sim_driver(cfg, hub, seed), "sim")


def build_audio(config: Config, hub: Hub) -> Service | None:
    """Microphone -> ``SpeechOut`` on the bus; ``SpeechIn`` from the bus -> speaker (ALSA or simulated)."""
    from feelium.audio.backends import AlsaMicrophone, AlsaSpeaker, Microphone, SimMicrophone, SimSpeaker, Speaker
    from feelium.audio.backends import alsa_available
    from feelium.audio.service import AudioService

    cfg = config.audio
    if cfg.backend == "off":
        return None
    use_alsa = cfg.backend == "alsa" or (cfg.backend == "auto" and alsa_available())
    if use_alsa:
        speaker: Speaker = AlsaSpeaker(cfg.sample_rate, cfg.playback_device)
        microphone: Microphone = AlsaMicrophone(cfg.sample_rate, cfg.capture_device)
    else:
        speaker = SimSpeaker(cfg.sample_rate, hub.clock)
        microphone = SimMicrophone(cfg.sample_rate, cfg.sim_tone_hz, hub.clock)
    return AudioService(cfg, hub, speaker, microphone, "alsa" if use_alsa else "sim")


# --- answering: the skin -------------------------------------------------------------------------------------------


def build_projector(config: Config, hub: Hub, display: Display | None = None) -> Service | None:
    """Bus (touch, wearer actions) -> interaction rules -> answers and the face on the skin; ``hub.projector_video``.

    ``display``: where the frames go; by default the configured backend (``feelium bench board`` passes a
    framebuffer of its own, so the writes are measured as on the blimp)."""
    from feelium.projector.display import open_display
    from feelium.projector.service import ProjectorService

    size = (config.projector.width, config.projector.height)
    rear_roi = tuple(config.rear_camera.roi) if config.rear_camera.roi else None
    try:
        calibration = load_or_default(calibration_path(config.projector.calibration.file), size, rear_roi)  # type: ignore[arg-type]
    except CalibrationError as exc:
        log.error("projector calibration unusable (%s); using the uncalibrated map", exc)
        calibration = default_calibration(DEFAULT_CAMERA_SIZE, rear_roi or DEFAULT_ROI, size)  # type: ignore[arg-type]
    if display is None:
        display = open_display(config.projector.backend, config.projector.fb_device)
    from feelium.touch.face import face_for

    face = face_for(config.touch, calibration.camera_size)  # the touch side's u, v, for the canvas
    return ProjectorService(config.projector, config.interactions, hub, display, calibration, face)


def build_show_loop(
    config: Config, content: str, face_video: Path | None = None, config_file: str | Path | None = None
) -> tuple[ShowLoop, bytes | None]:
    """The projector driven outside the daemon (``feelium record --projector``) and the calibration file's
    bytes, which a take projected through it needs to be replayed (None for the flat back-light, which needs
    no map and is recorded without a stream).

    Raises ``ValueError`` naming what is missing: projecting the face or avatar through an uncalibrated
    stand-in map would record light that no replay can predict.
    """
    from feelium.projector.display import open_display
    from feelium.projector.renderer import Renderer
    from feelium.projector.showloop import ShowLoop
    from feelium.touch.config import TouchConfig
    from feelium.touch.face import face_for

    size = (config.projector.width, config.projector.height)
    rear_roi = tuple(config.rear_camera.roi) if config.rear_camera.roi else None
    path = calibration_path(config.projector.calibration.file, config_file)  # where `calibrate projector --config` saved it
    data: bytes | None = None
    if content == "flat":
        calibration = default_calibration(DEFAULT_CAMERA_SIZE, rear_roi or DEFAULT_ROI, size)  # type: ignore[arg-type]
    else:
        if not path.is_file():
            raise ValueError(f"no projector calibration at {path}: run `feelium calibrate projector` first")
        try:
            calibration = load_or_default(path, size, rear_roi)  # type: ignore[arg-type]
        except CalibrationError as exc:
            raise ValueError(f"projector calibration {path} unusable: {exc}") from exc
        data = path.read_bytes()
    renderer = Renderer(config.projector, calibration, face_for(config.touch, calibration.camera_size))
    display = open_display(config.projector.backend, config.projector.fb_device)
    return ShowLoop(renderer, display, fps=config.projector.fps, content=content, face_video=face_video), data


# --- moving: the headset's commands reach the motors ---------------------------------------------------------------


def build_flight(config: Config, hub: Hub) -> Service | None:
    """``hub.motion`` (dead-man commands) and touch softening -> controller -> MSP motor board (or the simulated one)."""
    from feelium.flight.service import FlightService, LinkOpener, SerialOpener, SimOpener, resolve_backend

    flight = config.flight
    backend = resolve_backend(flight)
    if backend == "off":
        return None
    if backend == "sim":
        opener: LinkOpener = SimOpener(flight, config.sim.seed, hub.clock)
    else:
        opener = SerialOpener(flight.port, flight.baudrate, flight.reply_timeout_s)
    return FlightService(flight, hub, opener)


# --- the link: everything above, to and from the headset -----------------------------------------------------------


def build_http(config: Config, hub: Hub) -> Service | None:
    """The headset's API: video, events, motion, face and speech, all through the hub."""
    from feelium.http.app import SpeechSettings, create_app
    from feelium.http.auth import load_or_create_token
    from feelium.http.service import HttpService, tls_context

    if not config.http.enabled:
        return None
    token = load_or_create_token(config.http.token, config.http.token_file)
    tls_context(config.http)  # fail at build time, with the daemon's report, on a bad certificate pair
    speech = SpeechSettings.from_audio(config.audio)
    app = create_app(config.http, hub, token, speech)
    return HttpService(config.http, hub, token, app)


SERVICES: tuple[tuple[str, ServiceBuilder], ...] = (
    ("touch", build_touch),
    ("front_camera", build_front_camera),
    ("thermal", build_thermal),
    ("audio", build_audio),
    ("projector", build_projector),
    ("flight", build_flight),
    ("http", build_http),
)

# Built and started before every other part, which are then built off the event loop while these run: the flight
# loop commands the motors (neutral until it has fresh telemetry) from the daemon's first moments, however long the
# cameras, the projector's maps or the API take to build (seconds on a Pi: docs/performance.md, *Start-up*).
STARTS_FIRST = frozenset({"flight"})


@dataclass
class Built:
    """The services that were built and, per part, why one could not be."""

    services: list[Service] = field(default_factory=list)
    failures: dict[str, str] = field(default_factory=dict)  # part -> "ErrorType: message"


def build_services(config: Config, hub: Hub, builders: tuple[tuple[str, ServiceBuilder], ...] = SERVICES) -> Built:
    """Build every part; a part that fails is logged with its traceback and reported (and retried), the rest still start."""
    built = Built()
    for part, build in builders:
        try:
            service = build(config, hub)
            if service is not None and not isinstance(service, Service):
                raise TypeError(f"{part} built {service!r}, which is not a Service (name, stop_order, run, stop, health)")
        except ConfigError:
            raise  # a wrong setting (e.g. an unreadable TLS pair) stops the daemon: running without the part would hide it
        except Exception as exc:  # the traceback here; health reports the part failed (and logs that, once)
            log.warning("cannot build %s: %s", part, exc, exc_info=True)
            built.failures[part] = f"{type(exc).__name__}: {exc}"
            continue
        if service is None:
            log.debug("%s: off in the config", part)
        elif any(s.name == service.name for s in built.services):
            built.failures[part] = f"duplicate service name {service.name!r}"
            log.warning("cannot build %s: duplicate service name %r", part, service.name)
        else:
            built.services.append(service)
            log.debug("%s: %s", part, service.name)
    return built


# --- wiring shared between parts -----------------------------------------------------------------------------------


def load_projector_annotation(config: Config, path: Path | None = None) -> ProjectorAnnotation | None:
    """The annotation when a projector calibration file exists (``[projector.calibration] file``), else ``None``.

    Without ``feelium calibrate projector`` having run there is nothing to
    map through, and events pass unchanged. A file that exists but cannot be
    used is logged and ignored: touch sensing must not depend on it.
    """
    path = path if path is not None else calibration_path(config.projector.calibration.file)
    if not path.exists():
        log.info("touch: no projector calibration at %s; touch events carry camera coordinates only", path)
        return None
    try:
        from feelium.touch.face import face_for

        calibration = load_shared(path)  # the projector's own map: one copy
        face = face_for(config.touch, calibration.camera_size)
        annotation = ProjectorAnnotation(calibration, Regions.from_config(config.interactions), face)
    except Exception as exc:
        log.error("touch: projector calibration %s unusable (%s); touch events are not annotated", path, exc)
        return None
    log.info("touch: annotating touch events with projector coordinates from %s", path)
    return annotation


def load_projected_light(config: Config, backend: str, path: Path | None = None) -> ProjectedFactory | None:
    """How to predict each projector frame's light per camera frame size, or ``None`` when it must not be used.

    The projector is the rear camera's back-light, so the face it shows dims the membrane like a shadow
    would; the touch service mixes the predicted light of the frames each exposure integrated and the
    pipeline compensates it (``projected_light``, docs/touch.md). Only frames that contain the projector's light
    may be compensated: the real camera's. Compensating simulated or replayed frames would invent changes
    that are not in them, so ``auto`` keeps it for picamera2 with a calibration file.
    """
    mode = config.rear_camera.projection_compensation
    if mode == "off" or (mode == "auto" and backend != "picamera2"):
        return None
    path = path if path is not None else calibration_path(config.projector.calibration.file)
    if not path.exists():
        if mode == "on":
            log.warning("touch: projection_compensation is on but there is no projector calibration at %s", path)
        return None
    try:
        from feelium.projector.canvaslight import CanvasLightPredictor
        from feelium.touch.face import face_for

        calibration = load_shared(path)  # the projector's own map: one copy
        face = face_for(config.touch, calibration.camera_size)  # the projector's canvas spans the same u, v
    except Exception as exc:
        log.error("touch: projector calibration %s unusable (%s); no projection compensation", path, exc)
        return None
    if calibration.projector_size != (config.projector.width, config.projector.height):
        # The projector renders through its uncalibrated stand-in then: this map would put its canvas elsewhere.
        log.error("touch: %s is for a %s projector; no projection compensation", path, calibration.projector_size)
        return None
    log.info("touch: compensating the projected light in rear frames (calibration %s)", path)

    def for_frame_size(
        size: tuple[int, int],
        box: tuple[int, int, int, int] | None = None,
        average_of: int = 1,
        finer: CanvasLightPredictor | None = None,
    ) -> Callable[[np.ndarray], np.ndarray]:
        """Each projector frame's light from its grey skin canvas (``hub.projector_canvas``), over ``box`` (the
        touch pipeline's ROI, which is all it reads; default the whole frame); ``average_of`` and ``finer`` (the
        working grid's predictor, which predicts the fine pass's windows): see :class:`CanvasLightPredictor`."""
        return CanvasLightPredictor(
            config.projector, calibration, size, face, box, average_of=average_of, finer=finer
        )

    return for_frame_size
