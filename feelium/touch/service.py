"""The touch service: rear camera -> touch pipeline -> event bus (plus a debug view and the touch state).

A thin shell. The camera is read in a worker thread into a one-frame slot, so
the newest frame wins when the pipeline falls behind (drops are counted);
the pipeline and the overlay run in a worker thread too (OpenCV and numpy
release the GIL), so HTTP and serial stay responsive. Bad frames are counted
and skipped; anything else the pipeline raises crashes this service only, and
the supervisor restarts it with a fresh camera and pipeline.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
from collections.abc import Callable
from typing import Any

import numpy as np

from feelium.cameras.base import Frame
from feelium.cameras.reader import FrameSlot, RateMeter, Worker, close_camera, frame_condition, pump
from feelium.cameras.select import CameraSource
from feelium.events import TouchEvent
from feelium.hub import Hub
from feelium.skin.annotation import ProjectorAnnotation
from feelium.touch.config import TouchConfig
from feelium.touch.projected import ExposureLight, ProjectorHistory, history_window_s
from feelium.touch.sensing import SensingMonitor, SensingSample

log = logging.getLogger(__name__)

PipelineFactory = Callable[[TouchConfig, tuple[int, int], "tuple[int, int, int, int] | None"], Any]
# Per camera frame size (width, height): a projector frame to the light it puts on the membrane, camera frame size
# (``predict(canvas, out)``: ``out`` a recycled array to write into, or None; see ExposureLight).
ProjectedFactory = Callable[[tuple[int, int]], Callable[[np.ndarray, np.ndarray | None], np.ndarray]]
Overlay = Callable[[np.ndarray, Any, "tuple[int, int, int, int] | None"], np.ndarray]


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
        stale_after_s: float = 2.0,
    ) -> None:
        """``projected``: how to predict the light of each projector frame from its grey canvas
        (``hub.projector_canvas``), which then
        goes with every camera frame as ``projected_light`` (see :mod:`feelium.touch.projected`); ``None`` when
        the camera's frames hold no projection. Camera frames are stamped on the daemon's clock, the projector's
        frames too."""
        self.source = source
        self.hub = hub
        self.touch_config = touch_config
        self.debug_period = 1.0 / debug_video_fps if debug_video_fps > 0 else None
        self.pipeline_factory = pipeline_factory
        self.overlay = overlay
        self.annotation = annotation
        self.projected = projected
        self.stale_after_s = stale_after_s
        self.projector_history = ProjectorHistory(history_window_s(touch_config))
        self._exposure_light: ExposureLight | None = None
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
        self.cpu_s = 0.0  # worker-thread time spent in the pipeline (wall time of the calls)
        self._rate = RateMeter()
        self._pipeline: Any = None
        self._pipeline_key: tuple[Any, ...] | None = None
        self._last_debug: float | None = None
        self._slot: FrameSlot | None = None
        self._stopping = False

    async def run(self) -> None:
        self._pipeline, self._pipeline_key = None, None  # a restart starts from a fresh reference
        self._stopping = False
        camera_worker = Worker("rear-camera")
        try:
            camera = await camera_worker.call(self.source.open)
        except BaseException:
            camera_worker.shutdown()
            raise
        self.opens += 1
        log.info("touch: rear camera on the %s backend", self.source.backend)
        slot = self._slot = FrameSlot()
        reader = asyncio.create_task(pump(camera, slot, camera_worker), name="touch.camera")
        follower = asyncio.create_task(self._follow_projector(), name="touch.projector") if self.projected else None
        pipeline_worker = Worker("touch-pipeline")
        try:
            await self._consume(slot, pipeline_worker)
            if not self._stopping:
                await reader  # the source ended: re-raise a camera error, if that was why
        finally:
            self.dropped_frames += slot.dropped
            self._slot = None
            reader.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await reader
            if follower is not None:
                follower.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await follower
            pipeline_worker.shutdown()
            await close_camera(camera, camera_worker)

    async def _consume(self, slot: FrameSlot, worker: Worker) -> None:
        while True:
            frame = await slot.take()
            if frame is None:
                self._flush()
                log.info("touch: %s after %d frames", "stopped" if self._stopping else "rear camera source ended", self.frames)
                return
            problem = _check_frame(frame.image)
            if problem is not None:
                self._reject(problem)
                continue
            pipeline = self._pipeline_for(frame)
            want_debug = self.debug_period is not None and (
                self._last_debug is None or frame.t - self._last_debug >= self.debug_period or frame.t < self._last_debug
            )
            loop = asyncio.get_running_loop()
            started = loop.time()
            try:
                result, debug = await worker.call(self._step, pipeline, frame, want_debug)
            except ValueError as exc:  # bad input (e.g. a timestamp that goes backwards): count and skip
                self._reject(str(exc))
                continue
            self.cpu_s += loop.time() - started
            self._publish(frame, result, debug)

    async def _follow_projector(self) -> None:
        """Record the canvas of every frame the projector service shows (newest-wins slot, woken on each publish)."""
        seq = 0
        while True:
            item = await self.hub.projector_canvas.next_after(seq, timeout=1.0)
            if item is not None and item.seq > seq:
                seq = item.seq
                self.projector_history.record(item.t, item.seq, item.value)

    def _step(self, pipeline: Any, frame: Frame, want_debug: bool) -> tuple[Any, np.ndarray | None]:
        """Worker-thread part: the pipeline and, at the debug rate, the overlay."""
        projected = self._projected_light(frame.t)
        if projected is None:
            result = pipeline.process(frame.t, frame.image)
        else:
            light, spread = projected
            result = pipeline.process(frame.t, frame.image, projected_light=light, projected_spread=spread)
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

    def _pipeline_for(self, frame: Frame) -> Any:
        size = (int(frame.image.shape[1]), int(frame.image.shape[0]))
        key = (frame.segment, size, frame.roi)
        if self._pipeline is None or key != self._pipeline_key:
            self._flush()
            self._pipeline = self.pipeline_factory(self.touch_config, size, frame.roi)
            self._pipeline_key = key
            self._frame_size = size
            self._exposure_light = (
                ExposureLight(self.projected(size), self.touch_config) if self.projected is not None else None
            )
            self._last_debug = None
        return self._pipeline

    def _sense(self, t: float) -> None:
        """Feed the light monitor from the pipeline that just ran (on the loop's thread, as health reads it)."""
        pipeline = self._pipeline
        masked, geometry = getattr(pipeline, "masked", None), getattr(pipeline, "geometry", None)
        if masked is None or geometry is None:
            return
        response = getattr(pipeline, "response", None)
        width, height = geometry.work_size
        self.sensing.update(SensingSample(
            t=t, pixels=int(width * height), dark=masked.dark, saturated=masked.saturated,
            projector_share=None if response is None else response.share,
        ))  # fmt: skip

    def _flush(self) -> None:
        """Release contacts still down when a segment ends, so no consumer waits for an ``up`` forever."""
        finish = getattr(self._pipeline, "finish", None)
        if finish is None:
            return
        for event in finish():
            self._publish_event(event)

    def _publish(self, frame: Frame, result: Any, debug: np.ndarray | None) -> None:
        now = self.hub.clock()
        self._sense(frame.t)
        for event in result.events:
            self._publish_event(event)
        self.frames += 1
        self.last_frame_at = now
        self._rate.tick(now)
        if debug is not None:
            self.hub.rear_video.publish(frame.t, debug)
            self._last_debug = frame.t
        self.hub.state.update(
            "touch",
            t=round(float(result.t), 4),
            activity=bool(result.activity),
            anchor=round(float(result.anchor), 3),
            depth_max=round(float(result.depth_max), 3),
            contacts=[_contact_state(c) for c in result.contacts],
            backend=self.source.backend,
        )

    def _publish_event(self, event: TouchEvent) -> None:
        if self.annotation is not None and self._frame_size is not None:
            event = self.annotation(event, self._frame_size)
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
            "bad_frames": self.bad_frames,
            "last_bad_frame": self.last_error,
            "opens": self.opens,
            "overlay_errors": self.overlay_errors,
            "last_overlay_error": self.last_overlay_error,
            "ms_per_frame": round(1000.0 * self.cpu_s / self.frames, 2) if self.frames else None,
            "last_frame_at": self.last_frame_at,
            "projection_compensation": self.projected is not None,
            "projector_frames": self.projector_history.recorded,
            "projected_errors": self.projected_errors,
            "last_projected_error": self.last_projected_error,
            "projector_annotation": None
            if self.annotation is None
            else {"errors": self.annotation.errors, "last_error": self.annotation.last_error},
        }
