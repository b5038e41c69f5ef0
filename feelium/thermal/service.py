"""The thermal service: sensor (or its simulation) -> decoder -> presence detector -> hub.

A thin shell. Bus work, decoding and presence detection run on a thread of the
service's own (``thermal``), paced by its own clock, so the event loop never waits
on I2C and is woken once per frame, not per poll: the thread hands each frame's
presence events and summary to the loop through a
:class:`~feelium.cameras.handoff.LoopInbox`, which publishes them on ``hub.bus``
and in ``hub.state["presence"]`` (the loop's part of a sub-page went from two or
three ``to_thread`` round trips, their sleeps and the detector to one batch;
docs/performance.md, session 22). Nothing here is fatal: an I2C error or a bad
EEPROM dump is counted, reported in ``health()``, and retried after a backoff that
doubles while failures continue.

In sim (``backend = "sim"``, or ``auto`` without an I2C bus) the
simulated sensor sees the scene renderer's frames: the live simulator's warm
bodies when it offers them (``hub.rear_scene.warm_bodies(t)``), else a
repeating demo visit.
"""

from __future__ import annotations

import asyncio
import math
import os
import threading
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from feelium.cameras.handoff import LoopInbox
from feelium.cameras.reader import Worker, frame_condition
from feelium.events import PresenceEvent
from feelium.hub import Hub
from feelium.thermal import registers as reg
from feelium.thermal.calibration import CalibrationError
from feelium.thermal.config import ThermalConfig
from feelium.thermal.decoder import FrameAssembler
from feelium.thermal.driver import Mlx90640Driver
from feelium.thermal.presence import PresenceDetector

MAX_BACKOFF_FACTOR = 8
FAILED_AFTER = 3  # attempts in a row that raised before health calls the sensor failed (one can be a glitch)
STALE_AFTER_FRAMES = 5  # frame periods without a frame before health calls a part that raises nothing degraded
MIN_STALE_AFTER_S = 1.0


class Detected(NamedTuple):
    """One frame's outcome, made on the thermal thread for the loop to publish."""

    events: list[PresenceEvent]
    presence: dict[str, Any]  # ``hub.state["presence"]``


def control_settings(config: ThermalConfig) -> reg.ControlSettings:
    return reg.ControlSettings(config.refresh_hz, config.resolution_bits, config.mode)


def smbus2_driver(config: ThermalConfig) -> Mlx90640Driver:
    from feelium.thermal.transport import SMBus2Transport

    transport = SMBus2Transport.open(config.i2c_bus, config.i2c_address, config.max_read_words, config.attempts)
    return Mlx90640Driver(transport, control_settings(config))


def sim_driver(config: ThermalConfig, hub: Hub, seed: int) -> Mlx90640Driver:
    """A driver on the simulated sensor, which sees the scene renderer's frames on the hub's clock."""
    from feelium.sim.thermal import ThermalSceneRenderer, demo_bodies
    from feelium.thermal.sim_device import SimMlx90640
    from feelium.thermal.transport import SMBus2Transport

    renderer = ThermalSceneRenderer(np.random.default_rng(seed), 22.0, fps=config.refresh_hz / 2)

    def scene(t: float) -> np.ndarray:
        live = getattr(hub.rear_scene, "warm_bodies", None)
        bodies = live(t) if callable(live) else demo_bodies(t)
        return renderer.frame(t, bodies)

    sensor = SimMlx90640(scene, clock=hub.clock, sleep=time.sleep, rng=np.random.default_rng(seed + 1), ta_c=29.0)
    transport = SMBus2Transport(sensor.bus(), sensor.device, config.max_read_words, config.attempts)
    return Mlx90640Driver(transport, control_settings(config))


class ThermalService:
    """Reads sub-pages, assembles frames, runs presence, publishes (see the module docstring)."""

    name = "thermal"
    stop_order = 50

    def __init__(
        self,
        config: ThermalConfig,
        hub: Hub,
        make_driver: Callable[[], Mlx90640Driver],
        source: str,
        sleep: Callable[[float], None] | None = None,
    ) -> None:
        """``sleep``: how the thermal thread waits between polls (tests pass a virtual clock's); by default it
        waits on the service's stop, so a stop ends a wait at once."""
        self.config = config
        self.sleep = sleep
        self.hub = hub
        self.make_driver = make_driver
        self.source = source
        self.driver: Mlx90640Driver | None = None
        self.assembler: FrameAssembler | None = None
        self.detector = PresenceDetector(config.presence)
        self.frames = 0
        self.events = 0
        self.failures = 0  # start or read attempts that raised
        self.last_error: str | None = None
        self.last_frame: np.ndarray | None = None
        self.last_ta: float | None = None
        self._frame_at: float | None = None  # hub time of the newest frame (set on the thermal thread)
        self._consecutive_failures = 0
        self._polled_at: float | None = None  # when the worker's newest poll began
        self._stopping = False
        self._ending = threading.Event()  # this run's thread should end (a new one per run: a restart after a crash)
        self._reading = threading.Lock()  # held by the one thread that may use the driver
        self._driver_closed = False  # a stopped or cancelled run's thread closed ``driver``

    def _backoff(self) -> float:
        factor = min(MAX_BACKOFF_FACTOR, 2 ** max(0, self._consecutive_failures - 1))
        return self.config.retry_backoff_s * factor

    def _start_driver(self) -> None:
        driver = self.make_driver()
        try:
            calibration = driver.start()
        except BaseException:
            driver.close()
            raise
        self.driver = driver
        self.assembler = FrameAssembler(calibration, self.config.emissivity, self.config.reflected_offset_c)

    def _read_once(self) -> tuple[float | None, np.ndarray | None]:
        """Worker thread: start if needed, poll one sub-page, decode it.

        Returns, when a new sub-page was read, the time it was known not to be ready yet (the poll before
        began then; ``None`` if none was read), and the new full frame (``None`` if there is none yet, or the
        sub-page was rejected)."""
        if self.driver is None:
            self._start_driver()
        assert self.driver is not None and self.assembler is not None
        polled_at = self.hub.clock()
        not_ready_at, self._polled_at = self._polled_at, polled_at
        words = self.driver.poll()
        if words is None:
            return None, None
        not_ready_at = polled_at if not_ready_at is None else not_ready_at  # the first: no bound, poll on
        image = self.assembler.add(words)
        if image is None or not self.assembler.complete:
            return not_ready_at, None
        return not_ready_at, image

    def _detect(self, t: float, image: np.ndarray) -> Detected:
        """Thermal thread: count the frame, run presence on it, summarise it for ``hub.state``."""
        self.frames += 1
        self._frame_at = t
        self.last_frame = image
        if self.assembler is not None and self.assembler.last is not None:
            self.last_ta = self.assembler.last.ta
        events = self.detector.step(t, image)
        cluster = self.detector.cluster if self.detector.present else None
        return Detected(events, dict(
            present=self.detector.present,
            t=round(t, 3),
            x=None if cluster is None else round(cluster.x, 2),
            y=None if cluster is None else round(cluster.y, 2),
            size=0 if cluster is None else cluster.size,
            peak_rise_c=None if cluster is None else round(cluster.peak_rise_c, 2),
            ambient_c=None if not np.isfinite(image).any() else round(float(np.nanmedian(image)), 2),
        ))  # fmt: skip

    def _publish(self, batch: list[Detected]) -> None:
        """On the loop: one wake-up's frames, in order."""
        for detected in batch:
            for event in detected.events:
                self.events += 1
                self.hub.bus.publish(event)
            self.hub.state.update("presence", **detected.presence)

    def _wait(self, seconds: float, ending: threading.Event) -> None:
        if self.sleep is not None:
            self.sleep(seconds)
        else:
            ending.wait(seconds)

    def _read_loop(self, inbox: LoopInbox[Detected], ending: threading.Event) -> None:
        """Thermal thread: :meth:`_poll_until_ended`, once the previous run's thread is gone.

        A cancelled run's thread ends only after its current read and then closes the driver: a run started
        meanwhile must neither read the bus alongside it nor go on with the driver it closed."""
        with self._reading:
            if self._driver_closed:
                self.driver, self._driver_closed = None, False
            self._poll_until_ended(inbox, ending)

    def _poll_until_ended(self, inbox: LoopInbox[Detected], ending: threading.Event) -> None:
        """Thermal thread: poll, decode, detect, hand over; between sub-pages, wait until the next one can be ready.

        The device finishes a sub-page every ``1 / refresh_hz``. One that a poll found was not ready when the
        poll before it began, at ``t`` (usually ``poll_s`` earlier; more when the thread was held up), so the
        next cannot be ready before ``t + period``: the thread waits until then and polls every ``poll_s`` from
        there. A sub-page still waits at most ``poll_s`` to be read, as with polling all the time, but it costs
        one or two polls (status reads) instead of four or five (32 a second at 8 Hz).
        """
        period_s = 1.0 / self.config.refresh_hz
        poll_s = 0.25 * period_s
        try:
            while not ending.is_set():
                try:
                    not_ready_at, image = self._read_once()
                except (OSError, CalibrationError) as exc:
                    self.failures += 1
                    self._consecutive_failures += 1
                    self.last_error = f"{type(exc).__name__}: {exc}"
                    if isinstance(exc, CalibrationError) and self.driver is not None:
                        self.driver.close()
                        self.driver = None
                    self._wait(self._backoff(), ending)
                    continue
                self._consecutive_failures = 0
                if not_ready_at is None:
                    self._wait(poll_s, ending)
                    continue
                now = self.hub.clock()
                if image is not None:
                    inbox.post(self._detect(now, image))
                self._wait(max(0.0, not_ready_at + period_s - now), ending)
        finally:
            if ending.is_set() and self.driver is not None:  # stopped; after a crash the restart goes on with it
                try:
                    self.driver.close()
                except OSError:
                    pass
                self._driver_closed = True  # kept for health(); a later run starts a new one

    async def run(self) -> None:
        """Run the thermal thread until the service stops (or the thread raises what it cannot handle)."""
        self._ending = ending = threading.Event()
        if self._stopping:
            return
        worker = Worker("thermal")
        inbox = LoopInbox(asyncio.get_running_loop(), self._publish)
        try:
            await worker.call(self._read_loop, inbox, ending)
        finally:
            ending.set()  # a cancelled run: the thread ends after its current read and closes the driver
            inbox.close()
            worker.shutdown()

    async def stop(self) -> None:
        self._stopping = True
        self._ending.set()  # the thread closes the driver: closing it here could cut a read in half

    def _condition(self) -> dict[str, str]:
        """Failing reads are the part's health: a missing or dead sensor must not read as ok."""
        if self._consecutive_failures >= FAILED_AFTER or (self._consecutive_failures and not self.frames):
            return {"condition": "failed", "reason": f"sensor failed {self._consecutive_failures} times in a row: {self.last_error}"}
        if self._consecutive_failures:
            return {"condition": "degraded", "reason": f"read failed, retrying: {self.last_error}"}
        # A sensor whose new-data bit never comes back, or a read stuck on the thread, raises nothing: only the
        # age of the newest frame tells (a full frame takes two sub-pages, ``2 / refresh_hz``).
        stale_after_s = max(MIN_STALE_AFTER_S, STALE_AFTER_FRAMES * 2.0 / self.config.refresh_hz)
        return frame_condition(self._frame_at, self.hub.clock(), stale_after_s, "thermal")

    def health(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            **self._condition(),
            "source": self.source,
            "frames": self.frames,
            "events": self.events,
            "failures": self.failures,
            "last_error": self.last_error,
            "present": self.detector.present,
            "ta_c": None if self.last_ta is None or not math.isfinite(self.last_ta) else round(self.last_ta, 2),
        }
        driver = self.driver  # read once: the thermal thread drops it after a bad calibration
        if driver is not None:
            out["driver"] = driver.health()
        if self.assembler is not None:
            out["decoded"] = self.assembler.decoded
            out["rejected"] = dict(self.assembler.rejected)
            out["nan_pixels"] = self.assembler.failed_pixels
        out["presence_skipped"] = self.detector.skipped
        return out


def choose_backend(config: ThermalConfig) -> str:
    """``smbus2`` or ``sim`` (``auto``: the real bus if its device node exists)."""
    if config.backend != "auto":
        return config.backend
    return "smbus2" if os.path.exists(f"/dev/i2c-{config.i2c_bus}") else "sim"


__all__ = ["ThermalService", "choose_backend", "sim_driver", "smbus2_driver"]
