"""The projector service: interaction engine + renderer + display, on the daemon's hub.

Each tick (at ``projector.fps``) it drains touch events and wearer actions
from the bus into the interaction engine, publishes the engine's
``InteractionEvent``s for the wearer's view, hands its motion replies to the
dead-man motion path (never over the wearer's own steering), decodes the
newest face JPEG if one arrived (a looping avatar's frames in its first two rounds only, :mod:`feelium.projector.facecache`), renders the frame in a worker thread and
shows it; the newest frame also goes to ``hub.projector_video``, stamped with
the time the display got it, for the HTTP preview, and its grey skin canvas to
``hub.projector_canvas``, stamped the same, for the touch service, which
compensates the light each camera exposure integrated. On a static skin it lays
the touch probe over the frame (``[projector] probe``, :mod:`feelium.projector.probe`) and publishes its level,
stamped the same, on ``hub.projector_probe`` (None on frames without it). Bad input (an undecodable JPEG, an out-of-range event) is counted
and skipped.
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Any

import cv2
import numpy as np

from feelium.cameras.reader import Worker
from feelium.events import TouchEvent, WearerAction
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
        self.counters: dict[str, Any] = {
            "frames": 0, "touch_events": 0, "actions": 0, "interaction_events": 0, "motions_sent": 0,
            "motions_skipped": 0, "faces": 0, "bad_faces": 0, "bad_events": 0, "render_ms": 0.0, "late_frames": 0, "last_error": None,
            "probe_frames": 0,
        }

    def step_engine(self, subscription: Any, now: float) -> None:
        """Feed what arrived on the bus to the engine, publish its events, send its motion replies."""
        for item in subscription.drain():
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
        for event in step.events:
            self.hub.bus.publish(event)
            self.counters["interaction_events"] += 1
        for motion in step.motions:
            self._send_motion(motion, now)

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

    async def update_face(self) -> None:
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
            face = await asyncio.to_thread(self._decode_face, item.value)
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
        # turns rendering, so each held one (docs/performance.md, *Resident memory*).
        render = Worker("projector-render")
        with self.hub.bus.subscribe((TouchEvent, WearerAction), maxsize=512) as subscription:
            try:
                await self._loop(subscription, period, render)
            finally:
                render.shutdown()
                self.display.close()

    async def _loop(self, subscription: Any, period: float, render: Worker) -> None:
        # Frames are due on an absolute schedule (the loop's clock, which its sleeps follow): sleeping "the rest
        # of the period" after each frame loses every wake-up's lateness (~2 % of 30 fps). A frame that finishes
        # after the next one was due is late; the schedule then restarts from now instead of rushing to catch up.
        loop = asyncio.get_running_loop()
        due = loop.time()
        while not self._stopping:
            now = self.hub.clock()
            self.step_engine(subscription, now)
            await self.update_face()
            answers = self.engine.answers(now) if self.engine is not None else ()
            probing = self.probing(now)
            frame, canvas, shown, level = await render.call(self._render_and_show, now, self._face, answers, probing)
            self.hub.projector_canvas.publish(shown, canvas)
            self.hub.projector_probe.publish(shown, level)
            self.counters["probe_frames"] += level is not None
            self.hub.projector_video.publish(shown, frame)
            self.counters["frames"] += 1
            due += period
            if due < loop.time():
                self.counters["late_frames"] += 1
                due = loop.time()
            await asyncio.sleep(due - loop.time())

    async def stop(self) -> None:
        self._stopping = True

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
