"""The projector service: interaction engine + renderer + display, on the daemon's hub.

Each tick (at ``projector.fps``) it drains touch events and wearer actions
from the bus into the interaction engine, publishes the engine's
``InteractionEvent``s for the wearer's view, hands its motion replies to the
dead-man motion path (never over the wearer's own steering), decodes the
newest face JPEG if one arrived (a looping avatar's frames in its first two rounds only, :mod:`feelium.projector.facecache`), renders the frame
and shows it; the newest frame also goes to ``hub.projector_video``, stamped with
the time the display got it, for the HTTP preview, and its grey skin canvas to
``hub.projector_canvas``, stamped the same, for the touch service, which
compensates the light each camera exposure integrated. On a static skin it lays
the touch probe over the frame (``[projector] probe``, :mod:`feelium.projector.probe`) and publishes its level,
stamped the same, on ``hub.projector_probe`` (None on frames without it). Bad input (an undecodable JPEG, an out-of-range event) is counted
and skipped.

The ticks run on the ``projector-render`` thread, on its own clock (as flight's serial thread runs its
ticks): the event loop is not woken for a frame. It is woken only for what needs it: the engine's
events, posted in batches to the bus (whose subscribers wait on the loop), and a frame that an HTTP
preview waits for (:meth:`feelium.hub.Latest.post`). Motion replies go to ``hub.motion``, which is
thread-safe; the canvas and probe listeners (the touch side's histories) run on this thread.
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable
from contextlib import suppress
from typing import Any

import cv2
import numpy as np

from feelium.bus import Subscription
from feelium.cameras.handoff import LoopInbox
from feelium.cameras.reader import Worker
from feelium.events import InteractionEvent, TouchEvent, WearerAction
from feelium.hub import Hub
from feelium.interactions.config import InteractionsConfig
from feelium.jpeginfo import JpegHeaderError, jpeg_size, reduction_for
from feelium.interactions.engine import InteractionEngine, MotionReply
from feelium.projector.config import ProjectorConfig
from feelium.projector.display import Display
from feelium.projector.facecache import DecodedFaces
from feelium.projector.probe import ProbeOverlay
from feelium.projector.renderer import Renderer
from feelium.skin.face import FaceModel
from feelium.skin.probe import AMPLITUDE, probe_level
from feelium.skin.projector_map import ProjectorMap
from feelium.skin.regions import Regions

log = logging.getLogger(__name__)

# A wearer's face that has not changed for this long is a still picture: the probe goes back on (auto). A video
# sends 10-30 frames a second; its own motion teaches touch the projector's share.
FACE_STILL_S = 1.0
# On shutdown or a cancel, run() waits this long for the render thread to end its frame before closing the display.
JOIN_S = 2.0
# Engine events waiting for the loop; beyond this the render thread waits for it (never reached in practice: a
# few events a second, the bus's own queues hold 512).
EVENTS_WAITING = 512

_REDUCED_FLAGS = {1: cv2.IMREAD_COLOR, 2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4, 8: cv2.IMREAD_REDUCED_COLOR_8}


def decode_reduced(jpeg: bytes, need_width: int, need_height: int) -> np.ndarray | None:
    """A JPEG decoded at the smallest of 1/8, 1/4, 1/2, 1/1 scale that still covers ``need_width`` x
    ``need_height`` (libjpeg scales while decoding: a large upload never exists in memory at full size);
    ``None`` when its header or data cannot be read."""
    try:
        width, height = jpeg_size(jpeg)
    except JpegHeaderError:
        return None
    factor = reduction_for(width, height, need_width, need_height)
    return cv2.imdecode(np.frombuffer(jpeg, np.uint8), _REDUCED_FLAGS[factor])

class ProjectorService:
    """Renders the skin at a fixed rate and runs the six exchanges."""

    name = "projector"
    stop_order = 40

    def __init__(
        self,
        config: ProjectorConfig,
        interactions: InteractionsConfig,
        hub: Hub,
        display: Display,
        calibration: ProjectorMap,
        face: FaceModel | None = None,
    ) -> None:
        """``face``: the touch side's face model (``[touch] face_model``) for the calibration's camera frames, so
        answers are drawn at the touch's u, v on the face; ``None``: u, v across the calibration's ROI."""
        self.config = config
        self.hub = hub
        self.display = display
        self.calibration = calibration
        self.renderer = Renderer(config, calibration, face)
        self.engine = InteractionEngine(interactions, Regions.from_config(interactions)) if interactions.enabled else None
        self._face: np.ndarray | None = None
        self._face_seq = 0
        self._face_at = -np.inf  # when the last new face frame arrived (the daemon's clock)
        self._faces = DecodedFaces(int(config.face_cache_mb * 2**20))
        self._overlay: ProbeOverlay | None = None  # built on the first frame that carries the probe (0.15 s: a map fit)
        self._stopping = False
        self._halt = threading.Event()  # this run's: set by stop() and at the end of run(); wakes the frame wait
        self.counters: dict[str, Any] = {
            "frames": 0, "touch_events": 0, "actions": 0, "interaction_events": 0, "motions_sent": 0,
            "motions_skipped": 0, "faces": 0, "bad_faces": 0, "bad_events": 0, "render_ms": 0.0, "late_frames": 0, "last_error": None,
            "probe_frames": 0,
        }

    def step_engine(
        self, subscription: Subscription[Any], now: float, publish: Callable[[list[InteractionEvent]], None] | None = None
    ) -> None:
        """Feed what arrived on the bus to the engine, publish its events, send its motion replies.

        Runs on any thread (the bus items are taken, ``hub.motion`` is thread-safe); ``publish`` gets the step's
        events (default: straight onto the bus, for a caller on the event loop)."""
        for item in subscription.take():
            try:
                if isinstance(item, TouchEvent):
                    self.counters["touch_events"] += 1
                    if self.engine is not None:
                        self.engine.touch(item, now)
                elif isinstance(item, WearerAction):
                    self.counters["actions"] += 1
                    if self.engine is not None:
                        self.engine.action(item, now)
            except (ValueError, TypeError, KeyError) as exc:
                self.counters["bad_events"] += 1
                self.counters["last_error"] = f"{type(item).__name__}: {exc}"
        if self.engine is None:
            return
        step = self.engine.tick(now)
        if step.events:
            (publish or self._publish_events)(list(step.events))
            self.counters["interaction_events"] += len(step.events)
        for motion in step.motions:
            self._send_motion(motion, now)

    def _publish_events(self, events: list[InteractionEvent]) -> None:
        """On the loop: the engine's events onto the bus, in order."""
        for event in events:
            self.hub.bus.publish(event)

    def _send_motion(self, motion: MotionReply, now: float) -> None:
        active = self.hub.motion.active(now)
        if active is not None and active.source != "interaction":
            self.counters["motions_skipped"] += 1  # the wearer is steering: a reply never overrides them
            return
        try:
            self.hub.motion.command(motion.name, now, motion.hold_s, source="interaction")
            self.counters["motions_sent"] += 1
        except ValueError as exc:
            self.counters["motions_skipped"] += 1
            self.counters["last_error"] = str(exc)

    def _decode_face(self, jpeg: Any) -> np.ndarray | None:
        """The face fitted to the canvas; ``None`` when it is not a readable JPEG."""
        if isinstance(jpeg, np.ndarray) and jpeg.ndim == 3:
            return self.renderer.fit_face(jpeg)
        image = decode_reduced(bytes(jpeg), *self.renderer.canvas_size)
        return None if image is None else self.renderer.fit_face(image)

    def update_face(self) -> None:
        """Take up the newest face, decoded here (the render thread: a decode delays that frame, as awaiting it
        from the pool did)."""
        item = self.hub.face.get()
        if item is None or item.seq == self._face_seq:
            return
        self._face_seq = item.seq
        self._face_at = self.hub.clock()
        if item.value is None:  # the wearer cleared the face: back to the default avatar
            self._face = None
            self._faces.clear()
            return
        face = self._faces.get(item.value, self._face_at)  # a looping avatar's frame shown before
        if face is None:
            face = self._decode_face(item.value)
            if face is not None:
                face = self._faces.put(item.value, face, self._face_at)
        if face is None:
            self.counters["bad_faces"] += 1
        else:
            self._face = face  # shown until the wearer replaces or clears it, however long that is
            self.counters["faces"] += 1

    def probing(self, now: float) -> bool:
        """Whether this frame carries the probe: ``on``, or ``auto`` while no wearer video plays (the avatar or a
        face unchanged for :data:`FACE_STILL_S`)."""
        if self.config.probe == "off":
            return False
        return self.config.probe == "on" or self._face is None or now - self._face_at >= FACE_STILL_S

    def _render_and_show(
        self, now: float, face: np.ndarray | None, answers: tuple, probing: bool
    ) -> tuple[np.ndarray, np.ndarray, float, float | None]:
        """The frame, its grey canvas, the daemon-clock time the display got it (what the touch service's
        latency counts from) and the probe's level realised in it (None: no probe)."""
        start = time.perf_counter()
        frame, canvas = self.renderer.render_with_canvas(now, face, answers)
        level = None
        if probing:
            if self._overlay is None:
                self._overlay = ProbeOverlay(self.config, self.calibration)
            frame, level = self._overlay.lay(frame, probe_level(now, AMPLITUDE))
        self.display.show(frame)
        shown = self.hub.clock()
        self.counters["render_ms"] = round((time.perf_counter() - start) * 1000.0, 2)
        return frame, canvas, shown, level

    async def run(self) -> None:
        period = 1.0 / self.config.fps
        # Rendering runs on a thread of its own, not the shared pool: OpenCV 5 keeps a ~5.7 MB font cache in
        # every thread that draws text (the answers' labels) for the thread's life, and the pool's threads took
        # turns rendering, so each held one (docs/performance.md, *Resident memory*). The whole run is one job of
        # that thread (:meth:`_frames`).
        render = Worker("projector-render")
        loop = asyncio.get_running_loop()
        halt = self._halt = threading.Event()
        if self._stopping:
            halt.set()
        events = LoopInbox(loop, self._publish_events_batches, limit=EVENTS_WAITING)
        with self.hub.bus.subscribe((TouchEvent, WearerAction), maxsize=512) as subscription:
            frames = asyncio.ensure_future(render.call(self._frames, loop, subscription, period, halt, events))
            try:
                await asyncio.shield(frames)
            finally:
                halt.set()  # a cancel or a crash elsewhere: the thread ends after its frame
                events.close()
                if not frames.done():
                    with suppress(Exception):
                        await asyncio.wait_for(asyncio.shield(frames), JOIN_S)
                render.shutdown()
                self.display.close()  # after the thread's last show (or JOIN_S of a stuck one)

    def _publish_events_batches(self, batches: list[list[InteractionEvent]]) -> None:
        """On the loop: the batches of events the render thread posted, in order."""
        for events in batches:
            self._publish_events(events)

    def _frames(
        self, loop: asyncio.AbstractEventLoop, subscription: Subscription[Any], period: float, halt: threading.Event,
        events: LoopInbox[list[InteractionEvent]],
    ) -> None:
        """Render thread, the whole run: one frame per ``period`` until halted or the event loop is gone.

        Frames are due on an absolute schedule (the hub's clock): sleeping "the rest of the period" after each
        frame loses every wake-up's lateness (~2 % of 30 fps). A frame that finishes after the next one was due is
        late; the schedule then restarts from now instead of rushing to catch up. A loop that no longer runs ends
        the job too (a blocked one does not): nothing would stop it, and the interpreter's exit would wait for it.
        """
        due = self.hub.clock()
        while not (self._stopping or halt.is_set()) and loop.is_running():
            now = self.hub.clock()
            self.step_engine(subscription, now, events.post)
            self.update_face()
            answers = self.engine.answers(now) if self.engine is not None else ()
            probing = self.probing(now)
            frame, canvas, shown, level = self._render_and_show(now, self._face, answers, probing)
            self.hub.projector_canvas.post(loop, shown, canvas)
            self.hub.projector_probe.post(loop, shown, level)
            self.counters["probe_frames"] += level is not None
            self.hub.projector_video.post(loop, shown, frame)
            self.counters["frames"] += 1
            due += period
            done = self.hub.clock()
            if due < done:
                self.counters["late_frames"] += 1
                due = done
            halt.wait(due - done)

    async def stop(self) -> None:
        self._stopping = True
        self._halt.set()

    def health(self) -> dict[str, Any]:
        report = dict(self.counters)
        report["display"] = self.display.name
        report["display_writes"] = self.display.frames  # the framebuffer skips a frame it already holds; sim counts each
        report["calibration"] = self.calibration.source
        report["rendered"] = self.renderer.rendered  # the rest of "frames" showed the previous frame again
        report["faces_decoded"] = self._faces.misses  # the rest of "faces" came from the decoded faces kept
        report["faces_kept_mb"] = round(self._faces.bytes / 2**20, 1)
        if self.engine is not None:
            report["engine"] = dict(self.engine.counts)
        return report
