"""The touch service: rear camera -> touch pipeline -> event bus (plus a debug view and the touch state).

A thin shell. The camera is read in its own thread into a one-frame slot, so
the newest frame wins when the pipeline falls behind (drops are counted);
the pipeline and the overlay run in a second thread, which takes frames from
that slot directly (OpenCV and numpy release the GIL), so HTTP and serial stay
responsive. Only what must be published goes to the event loop, through a
:class:`~feelium.cameras.handoff.LoopInbox`: one loop wake-up per frame instead
of nine (docs/performance.md). Bad frames are counted and skipped; anything
else the pipeline raises crashes this service only, and the supervisor
restarts it with a fresh camera and pipeline.

The projector tells touch what it showed: the grey canvas of each frame
(``hub.projector_canvas``, for the projected content's light when it is
compensated) and the level of the probe it laid over a static skin
(``hub.projector_probe``, :mod:`feelium.skin.probe`), which goes with every
camera frame as ``probe_light``, mixed over that frame's exposure with the
projector's latency, so the pipeline learns the projector's share of the light
per place (the lit room's hover gate).

A replayed rear camera was lit by the projector of its recording, not by this
one: touch then listens to neither the canvases nor the probe of the live
projector (mixing two light sources would compensate light the frames never
had), and a recording that carries its projector stream brings its shown frames
with each camera frame (``Frame.shown``), predicted through the recording's map
(``stream_light``) exactly as ``feelium replay`` does. Health says which light
source touch compensates (``light_source``).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from feelium.cameras.base import Frame, ProjectorStream
from feelium.cameras.handoff import LoopInbox, ThreadSlot, read_into
from feelium.cameras.reader import RateMeter, Worker, close_camera, frame_condition
from feelium.cameras.select import CameraSource
from feelium.events import TouchEvent
from feelium.hub import Hub, Stamped
from feelium.skin.annotation import ProjectorAnnotation
from feelium.skin.probe import ProbeLevels, light_at, pattern_on_grid, probe_pattern
from feelium.touch.config import TouchConfig
from feelium.touch.projected import ExposureLight, ProjectorHistory, history_window_s
from feelium.touch.sensing import SensingMonitor, SensingSample, sample_of, share_taught

log = logging.getLogger(__name__)

PipelineFactory = Callable[[TouchConfig, tuple[int, int], "tuple[int, int, int, int] | None"], Any]
# Per camera frame size (width, height) and box [x, y, w, h] (the pipeline's ROI, or None for the whole frame): a
# projector frame to the light it puts on the membrane over that box (``predict(canvas, out)``: ``out`` a recycled
# array to write into, or None; see ExposureLight). A pipeline that detects coarser asks for its detection grid with
# two more arguments, ``average_of`` (LightGrids) and the working grid's predictor (asked for first), and uses that
# one's ``window(canvas, rows, cols)`` when it has one.
ProjectedFactory = Callable[..., Callable[[np.ndarray, np.ndarray | None], np.ndarray]]
# A replayed recording's projector stream -> how to predict its frames' light, and the touch config (the latency its
# map measured) each exposure is mixed with. Raises when the stream cannot be predicted (no map, a map of another size).
StreamLight = Callable[[ProjectorStream], tuple[ProjectedFactory, TouchConfig]]
Overlay = Callable[[np.ndarray, Any, "tuple[int, int, int, int] | None"], np.ndarray]


@dataclass(frozen=True)
class Processed:
    """A frame the pipeline processed, with what the loop publishes for it."""

    frame: Frame
    result: Any
    debug: np.ndarray | None
    sample: SensingSample | None
    frame_size: tuple[int, int] | None


@dataclass(frozen=True)
class Rejected:
    """A frame that could not go through the pipeline, and why."""

    reason: str


@dataclass(frozen=True)
class Released:
    """Contacts a pipeline released when its segment ended (at the frame size they were found at)."""

    events: tuple[TouchEvent, ...]
    frame_size: tuple[int, int] | None


Delivery = Processed | Rejected | Released


def _default_pipeline(config: TouchConfig, size: tuple[int, int], roi: tuple[int, int, int, int] | None) -> Any:
    """The pipeline for one camera frame size; with ``[touch] face_model`` it senses the whole face (the camera's
    ROI is then ignored: the face's own box is cut out) and its events carry the face's u, v."""
    from feelium.touch.face import face_for
    from feelium.touch.pipeline import TouchPipeline

    face = face_for(config, size)
    return TouchPipeline(config, size, None if face is not None else roi, face=face)


def _default_overlay(frame: np.ndarray, result: Any, roi: tuple[int, int, int, int] | None) -> np.ndarray:
    from feelium.touch.overlay import draw_overlay

    return draw_overlay(frame, result, roi)


def _contact_state(contact: Any) -> dict[str, Any]:
    """A contact as plain JSON-able values for the state board."""
    values = dataclasses.asdict(contact) if dataclasses.is_dataclass(contact) else dict(vars(contact))
    out: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(value, (bool, int, str)):
            out[key] = value
        elif isinstance(value, float):
            out[key] = round(value, 3) if np.isfinite(value) else None
    return out


def _check_frame(image: Any) -> str | None:
    """Why a frame cannot go to the pipeline, or ``None``."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        return "frame is not a uint8 array"
    if image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3):
        return None if min(image.shape[:2]) > 0 else "frame is empty"
    return f"frame has shape {image.shape}; expected (H, W) gray or (H, W, 3) BGR"


class TouchService:
    """Runs the touch pipeline on the rear camera and publishes what it finds."""

    name = "touch"
    stop_order = 40

    def __init__(
        self,
        source: CameraSource,
        hub: Hub,
        touch_config: TouchConfig,
        *,
        debug_video_fps: float = 5.0,
        pipeline_factory: PipelineFactory = _default_pipeline,
        overlay: Overlay = _default_overlay,
        annotation: ProjectorAnnotation | None = None,
        projected: ProjectedFactory | None = None,
        stream_light: StreamLight | None = None,
        stale_after_s: float = 2.0,
    ) -> None:
        """``projected``: how to predict the light of each projector frame from its grey canvas
        (``hub.projector_canvas``), which then
        goes with every camera frame as ``projected_light`` (see :mod:`feelium.touch.projected`); ``None`` when
        the camera's frames hold no projection. Camera frames are stamped on the daemon's clock, the projector's
        frames too. ``stream_light``: for a replayed camera, how to predict a recording's own projector stream
        (None: replays are not compensated)."""
        self.source = source
        self.hub = hub
        self.touch_config = touch_config
        self.debug_period = 1.0 / debug_video_fps if debug_video_fps > 0 else None
        self.pipeline_factory = pipeline_factory
        self.overlay = overlay
        self.annotation = annotation
        self.projected = projected
        self.stream_light = stream_light
        self.replayed = source.backend == "replay"  # lit by the recording's projector: the live one is not listened to
        self._active: ProjectedFactory | None = None if self.replayed else projected  # what this segment predicts from
        self._active_config = touch_config  # ... and mixes each exposure with
        self.light_source = self._live_light_source()
        self._shown_seq = 0  # the replayed projector frames, numbered as the projector numbers its own
        self.stale_after_s = stale_after_s
        self.projector_history = ProjectorHistory(history_window_s(touch_config))
        self.probe_levels = ProbeLevels(history_window_s(touch_config))
        self._probe_pattern: np.ndarray | None = None  # the probe's cells at the camera frame's size
        # The same cells on each grid the content's light may come on: the frame's, the ROI's cut, the detection
        # grid's; and the fine pass's windows' grid (``detect_scale`` < 1), with the level of the frame being sensed.
        self._probe_on_content: tuple[np.ndarray, ...] = ()
        self._probe_fine: np.ndarray | None = None
        self._probe_level: float | None = None
        self.probe_frames = 0  # camera frames that went to the pipeline with the probe's light
        self._exposure_light: ExposureLight | None = None
        self._windowed = False  # the pipeline takes the fine pass's light from self._window_light
        self.projected_errors = 0
        self.last_projected_error: str | None = None
        self._frame_size: tuple[int, int] | None = None
        self.frames = 0
        self.events = 0
        self.bad_frames = 0
        self.sensing = SensingMonitor()
        self.dropped_frames = 0
        self.opens = 0
        self.last_error: str | None = None
        self.overlay_errors = 0
        self.last_overlay_error: str | None = None
        self.last_frame_at: float | None = None
        self.cpu_s = 0.0  # pipeline-thread time spent in the pipeline (wall time of the calls)
        self._rate = RateMeter()
        self._pipeline: Any = None
        self._pipeline_key: tuple[Any, ...] | None = None
        self._last_debug: float | None = None
        self._slot: ThreadSlot | None = None
        self._inbox: LoopInbox[Delivery] | None = None
        self._delivery_error: Exception | None = None
        self._past_wakeups = 0  # loop wake-ups of earlier runs' inboxes
        self._stopping = False

    async def run(self) -> None:
        self._pipeline, self._pipeline_key = None, None  # a restart starts from a fresh reference
        self._stopping = False
        self._delivery_error = None
        camera_worker = Worker("rear-camera")
        try:
            camera = await camera_worker.call(self.source.open)
        except BaseException:
            camera_worker.shutdown()
            raise
        self.opens += 1
        log.info("touch: rear camera on the %s backend", self.source.backend)
        slot = self._slot = ThreadSlot()
        inbox = self._inbox = LoopInbox(asyncio.get_running_loop(), self._deliver)
        live = not self.replayed
        unlisten = self.hub.projector_canvas.listen(self._record_projector) if self.projected and live else None
        unlisten_probe = self.hub.projector_probe.listen(self._record_probe) if live else None
        # Each thread runs one job for the whole run: frames go camera -> pipeline thread to thread, and the
        # results reach the loop through the inbox, one wake-up per frame (fewer when the loop lags).
        reading = asyncio.ensure_future(camera_worker.call(read_into, camera, slot))
        pipeline_worker = Worker("touch-pipeline")
        try:
            await pipeline_worker.call(self._process_frames, slot, inbox)
            log.info("touch: %s after %d frames", "stopped" if self._stopping else "rear camera source ended", self.frames)
            if self._delivery_error is not None:
                raise self._delivery_error
            if not self._stopping:
                await reading  # the source ended: re-raise a camera error, if that was why
        finally:
            slot.end()
            inbox.close()
            self.dropped_frames += slot.dropped
            self._past_wakeups += inbox.wakeups
            self._slot = self._inbox = None
            if unlisten is not None:
                unlisten()
            if unlisten_probe is not None:
                unlisten_probe()
            pipeline_worker.shutdown()
            await close_camera(camera, camera_worker)  # after the read loop, which ends with the slot
            with contextlib.suppress(Exception):
                await reading

    def _process_frames(self, slot: ThreadSlot, inbox: LoopInbox[Delivery]) -> None:
        """Pipeline-thread job for the whole run: take each frame, process it, post what the loop must publish."""
        while True:
            frame = slot.take()
            if frame is None:
                released = self._flush()
                if released.events:
                    inbox.post(released)
                return
            problem = _check_frame(frame.image)
            if problem is not None:
                inbox.post(Rejected(problem))
                continue
            pipeline, flushed = self._pipeline_for(frame)
            if flushed is not None and flushed.events:
                inbox.post(flushed)
            self._record_shown(frame)
            want_debug = self.debug_period is not None and (
                self._last_debug is None or frame.t - self._last_debug >= self.debug_period or frame.t < self._last_debug
            )
            started = time.perf_counter()
            try:
                result, debug = self._step(pipeline, frame, want_debug)
            except ValueError as exc:  # bad input (e.g. a timestamp that goes backwards): count and skip
                inbox.post(Rejected(str(exc)))
                continue
            self.cpu_s += time.perf_counter() - started
            if debug is not None:
                self._last_debug = frame.t
            inbox.post(Processed(frame, result, debug, self._sample(frame.t), self._frame_size))

    def _deliver(self, items: list[Delivery]) -> None:
        """On the loop: publish a batch from the pipeline thread, in order. A failure here crashes the service
        (the pipeline thread is stopped and ``run()`` raises it), as a failure in the pipeline does."""
        try:
            for item in items:
                if isinstance(item, Processed):
                    self._publish(item)
                elif isinstance(item, Rejected):
                    self._reject(item.reason)
                else:
                    for event in item.events:
                        self._publish_event(event, item.frame_size)
        except Exception as exc:
            self._delivery_error = exc
            if self._slot is not None:
                self._slot.end()
            if self._inbox is not None:
                self._inbox.close()

    def _record_projector(self, item: Stamped[Any]) -> None:
        """Record the canvas of every frame the projector service shows (called on the loop as it publishes)."""
        self.projector_history.record(item.t, item.seq, item.value)

    def _record_shown(self, frame: Frame) -> None:
        """Record the projector frames a replayed recording showed up to this camera frame (on the pipeline thread,
        which alone reads the history while replaying)."""
        if self._active is None:
            return
        for t, shown in frame.shown:
            self.projector_history.record(t, self._shown_seq, shown)
            self._shown_seq += 1

    def _live_light_source(self) -> str:
        """What the live projector's light is, for health (a replay says its own per recording)."""
        if self.projected is not None:
            return "the projector's own frames, compensated"
        if self.replayed:
            return "replay: no frame yet"
        return "not compensated (this camera's frames hold no projected light to predict); the probe when laid"

    def _replay_light(self, stream: ProjectorStream | None) -> None:
        """Choose what the replayed recording now starting is compensated with: its own projector stream through its
        map, else nothing (a stream that cannot be predicted is reported in health, not guessed)."""
        self._active, self._active_config = None, self.touch_config
        if stream is None:
            self.light_source = "replay without a projector stream: the projected light is not compensated"
            return
        if self.stream_light is None:
            self.light_source = f"replay of {stream.recording}: its projector stream is not used (compensation off)"
            return
        try:
            self._active, self._active_config = self.stream_light(stream)
        except Exception as exc:  # the recording plays on, blind to its face: health says so
            self.projected_errors += 1
            self.last_projected_error = f"{type(exc).__name__}: {exc}"
            self.light_source = f"replay of {stream.recording}: its projector stream is NOT compensated ({exc})"
            log.warning("touch: %s", self.light_source)
            return
        self.light_source = f"replay of {stream.recording}: its recorded projector stream, map {stream.calibration}"
        log.info("touch: %s", self.light_source)

    def _record_probe(self, item: Stamped[Any]) -> None:
        """Record the probe's level in every frame the projector service shows (None: a frame without it)."""
        self.probe_levels.record(item.t, item.value)

    def _step(self, pipeline: Any, frame: Frame, want_debug: bool) -> tuple[Any, np.ndarray | None]:
        """Worker-thread part: the pipeline and, at the debug rate, the overlay."""
        projected = self._projected_light(frame.t)
        level = self._probe_level = self._probe_level_at(frame.t)
        if level is not None:
            self.probe_frames += 1
        if projected is None and level is None:
            result = pipeline.process(frame.t, frame.image)
        elif projected is None:
            assert self._probe_pattern is not None
            result = pipeline.process(frame.t, frame.image, probe_light=light_at(level, self._probe_pattern))
        else:
            light, spread = projected
            fine = {} if not self._windowed else {"fine_light": self._window_light}
            if level is not None:  # laid over the content after its canvas: its light multiplies the content's
                light = self._probe_over(light, level)
            result = pipeline.process(frame.t, frame.image, projected_light=light, projected_spread=spread, **fine)
        debug = None
        if want_debug:
            try:
                debug = self.overlay(frame.image, result, frame.roi)
            except Exception as exc:  # the debug view is a nicety: it must never take touch sensing down
                self.overlay_errors += 1
                self.last_overlay_error = f"{type(exc).__name__}: {exc}"
        return result, debug

    def _projected_light(self, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(light, spread) the exposure at ``t`` saw, or ``None``; a failing prediction costs only the compensation."""
        if self._exposure_light is None:
            return None
        try:
            return self._exposure_light(self.projector_history.frames(), t)
        except Exception as exc:
            self.projected_errors += 1
            self.last_projected_error = f"{type(exc).__name__}: {exc}"
            return None

    def _window_light(self, rows: slice, cols: slice) -> np.ndarray | None:
        """The last exposure's light at the pipeline's working resolution over a window of its fine pass, or None
        (the pipeline then upsamples its coarse light); a failing prediction costs only that window's detail."""
        assert self._exposure_light is not None
        try:
            window = self._exposure_light.window(rows, cols)
        except Exception as exc:
            self.projected_errors += 1
            self.last_projected_error = f"{type(exc).__name__}: {exc}"
            return None
        level, pattern = self._probe_level, self._probe_fine
        if window is not None and level is not None and pattern is not None:
            cut = pattern[rows, cols]
            if cut.shape == window.shape:  # a new array each call: the probe's light multiplies it in place
                window *= light_at(level, cut)
        return window

    def _exposure_light_for(self, size: tuple[int, int], box: tuple[int, int, int, int] | None) -> ExposureLight | None:
        """How each exposure's light is predicted for the new pipeline: over its ROI at the frame's size, or, when it
        detects at a coarser size (``light_grids``), on that grid, with the working resolution's light predicted in
        the fine pass's windows only (by the predictor's ``window``, when it has one)."""
        self._windowed = False
        projected, config = self._active, self._active_config
        if projected is None:
            return None
        grids = getattr(self._pipeline, "light_grids", None)
        if grids is None:
            return ExposureLight(projected(size, box), config)
        fine = None if grids.fine is None else projected(*grids.fine)
        coarse = projected(*grids.coarse, grids.average_of, fine)  # the fine one shares its canvas light
        self._windowed = True
        return ExposureLight(
            coarse, config, getattr(fine, "window", None), mixed_window=getattr(fine, "window_of_mix", None)
        )

    def _probe_level_at(self, t: float) -> float | None:
        """The probe's level the exposure at ``t`` saw, or None while the projector does not lay it."""
        if self._probe_pattern is None or not self.probe_levels.active():
            return None
        cfg = self.touch_config
        return self.probe_levels.level(t, cfg.camera_exposure_s, cfg.projector_latency_s)

    def _probe_over(self, light: np.ndarray, level: float) -> np.ndarray:
        """The content's light with the probe's over it, on the content light's grid (the frame's, the ROI's cut of
        it, or the detection grid's when it is coarser); the content's light alone on a grid of no other shape."""
        pattern = next((p for p in self._probe_on_content if p.shape == light.shape), None)
        return light if pattern is None else light * light_at(level, pattern)

    def _probe_grids(self, size: tuple[int, int], box: tuple[int, int, int, int] | None) -> None:
        """The probe's cells at the camera frame's size and on every grid the new pipeline reads light on."""
        camera = self._probe_pattern = probe_pattern(*size)  # cells of the same size on the skin at any resolution
        grids = getattr(self._pipeline, "light_grids", None) if self._windowed else None
        if grids is not None:  # the content's light comes on the detection grid, the fine pass's in windows
            self._probe_on_content = (pattern_on_grid(camera, *grids.coarse),)
            self._probe_fine = None if grids.fine is None else pattern_on_grid(camera, *grids.fine)
            return
        self._probe_on_content = (camera,) if box is None else (camera, pattern_on_grid(camera, size, box))
        self._probe_fine = None

    def _pipeline_for(self, frame: Frame) -> tuple[Any, Released | None]:
        """The pipeline for this frame's segment, size and ROI, and the contacts the one it replaces released."""
        size = (int(frame.image.shape[1]), int(frame.image.shape[0]))
        key = (frame.segment, size, frame.roi)
        flushed = None
        if self._pipeline is None or key != self._pipeline_key:
            flushed = self._flush()
            self._pipeline = self.pipeline_factory(self.touch_config, size, frame.roi)
            self._pipeline_key = key
            self._frame_size = size
            if self.replayed:  # each recording was lit by its own projector: its frames only, from its start
                self._replay_light(frame.stream)
                self.projector_history = ProjectorHistory(history_window_s(self._active_config))
            # Predicted only over the ROI the pipeline cuts (it takes light of the ROI's size or of the frame's).
            box = getattr(self._pipeline, "roi", None)
            self._exposure_light = self._exposure_light_for(size, box)
            self._probe_grids(size, box)
            self._last_debug = None
        return self._pipeline, flushed

    def _sample(self, t: float) -> SensingSample | None:
        """What the light monitor needs from the pipeline that just ran (read on its thread, used on the loop's)."""
        return sample_of(self._pipeline, t, self._share_taught())

    def _share_taught(self) -> bool:
        """Whether something teaches the pipeline the projector's share of the light (the probe, or projected
        content it compensates) for a hover gate that is on: its share must then become known."""
        fed = self.probe_levels.active() or self._exposure_light is not None
        return share_taught(self.touch_config.contact_projected_depth, fed)

    def _flush(self) -> Released:
        """Release contacts still down when a segment ends, so no consumer waits for an ``up`` forever."""
        finish = getattr(self._pipeline, "finish", None)
        return Released(tuple(finish()) if finish is not None else (), self._frame_size)

    def _publish(self, item: Processed) -> None:
        frame, result, debug = item.frame, item.result, item.debug
        now = self.hub.clock()
        if item.sample is not None:
            self.sensing.update(item.sample)
        for event in result.events:
            self._publish_event(event, item.frame_size)
        self.frames += 1
        self.last_frame_at = now
        self._rate.tick(now)
        if debug is not None:
            self.hub.rear_video.publish(frame.t, debug)
        self.hub.state.update(
            "touch",
            t=round(float(result.t), 4),
            activity=bool(result.activity),
            anchor=round(float(result.anchor), 3),
            depth_max=round(float(result.depth_max), 3),
            contacts=[_contact_state(c) for c in result.contacts],
            backend=self.source.backend,
        )

    def _publish_event(self, event: TouchEvent, frame_size: tuple[int, int] | None) -> None:
        if self.annotation is not None and frame_size is not None:
            event = self.annotation(event, frame_size)
        self.hub.bus.publish(event)
        self.events += 1

    def _reject(self, reason: str) -> None:
        self.bad_frames += 1
        self.last_error = reason
        if self.bad_frames <= 3 or self.bad_frames % 100 == 0:
            log.warning("touch: skipped a bad frame (%d so far): %s", self.bad_frames, reason)

    async def stop(self) -> None:
        self._stopping = True
        if self._slot is not None:
            self._slot.end()

    def health(self) -> dict[str, Any]:
        slot_drops = self._slot.dropped if self._slot is not None else 0
        now = self.hub.clock()
        condition = frame_condition(self.last_frame_at, now, self.stale_after_s, "rear camera")
        blind = self.sensing.reasons()
        if condition["condition"] == "ok" and blind:
            condition = {"condition": "degraded", "reason": "; ".join(blind)}
        return {
            **condition,
            "light": self.sensing.figures(),
            "backend": self.source.backend,
            "frames": self.frames,
            "fps": round(self._rate.rate(now), 2),
            "events": self.events,
            "dropped_frames": self.dropped_frames + slot_drops,
            "loop_wakeups": self._past_wakeups + (self._inbox.wakeups if self._inbox is not None else 0),
            "bad_frames": self.bad_frames,
            "last_bad_frame": self.last_error,
            "opens": self.opens,
            "overlay_errors": self.overlay_errors,
            "last_overlay_error": self.last_overlay_error,
            "ms_per_frame": round(1000.0 * self.cpu_s / self.frames, 2) if self.frames else None,
            "last_frame_at": self.last_frame_at,
            "projection_compensation": self._active is not None,
            "light_source": self.light_source,
            "projector_frames": self.projector_history.recorded,
            "probe": self.probe_levels.active(),
            "probe_frames": self.probe_frames,
            "projected_errors": self.projected_errors,
            "last_projected_error": self.last_projected_error,
            "projector_annotation": None
            if self.annotation is None
            else {"errors": self.annotation.errors, "last_error": self.annotation.last_error},
        }
