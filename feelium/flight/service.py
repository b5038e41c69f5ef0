"""The flight service: motor board link, control loop, failsafes, state on the hub.

A thin shell around :class:`FlightController`. While the board's link is
open, one job of the service's serial thread flies it: every period it waits
out the period on its own clock, polls the board, steps the controller with
the wearer's dead-man command and the soften flag (from the touch and
interaction events taken at the step), and commands the motors at once; the
loop only publishes altitude, heading, battery and link state, and takes up a
lost link. So the loop never blocks on the port, the port is never used from
two threads at once, a late event loop (an HTTP burst, a CPU quota) does not
delay the motors, and a tick costs at most one wake-up of the loop.
When the port disappears it keeps stepping the controller without telemetry
(which goes to its failsafe; the board's own watchdog stops the motors) and
reopens the port with a doubling backoff, capped
(``reconnect_max_s``, under 1 s) so a returning board is flown again within
a second. The link state in ``health()`` is ``up``, ``stalled`` (the board
went silent), ``resyncing`` (the client discards a backlog and waits for a
quiet line), ``down`` or ``connecting``; each change into a bad state is
logged once as a warning, the recovery once as info.

``stop()`` runs first on shutdown (``stop_order = 0``): it commands every
motor to neutral through the MSP client, as the very next job of the serial thread,
and stops the loop from commanding anything else. The serial thread belongs to one
``run()``: it opens the port and is the only thread that ever touches it, and a
``run()`` that ends for any reason leaves the motors neutral and the port closed.
"""

from __future__ import annotations

import asyncio
import logging
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import suppress
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

from feelium.bus import Subscription
from feelium.cameras.handoff import call_on
from feelium.cameras.reader import RateMeter
from feelium.events import InteractionEvent, TouchEvent
from feelium.flight.client import MspClient
from feelium.flight.config import FlightConfig
from feelium.priority import name_current_thread
from feelium.flight.controller import ControlOutput, FlightController
from feelium.flight.lateness import LatenessHistogram
from feelium.flight.altitude_health import AltitudeWatch
from feelium.flight.sensor_health import SensorWatch
from feelium.flight.setpoint import setpoint_for_motion
from feelium.flight.soften import SoftenTracker
from feelium.flight.telemetry import Telemetry
from feelium.flight.transport import ByteLink, open_serial
from feelium.hub import Hub

if TYPE_CHECKING:
    from feelium.flight.sim_board import SimMotorBoard

log = logging.getLogger(__name__)
STOP_WRITE_TIMEOUT_S = 0.3
NEUTRAL_DRAIN_S = 0.1  # after the neutral, the board's replies are read this long before the link closes (``_drain``)
PUBLISH_EVERY_S = 0.1  # the serial thread wakes the loop to publish the flight state at most this often
LOOP_STALL_S = 0.5  # no control cycle for this long (25 periods at 50 Hz): health says the loop stalled
LINK_COUNTERS = ("stalls", "resyncs", "late_replies")  # summed over every client a run opened
# At most this many link lines in any window this long; the changes beyond are counted into the next line.
LINK_LOG_BURST, LINK_LOG_WINDOW_S = 4, 10.0
LINK_REASONS = {
    "stalled": "no reply to the last telemetry requests; probing",
    "resyncing": "discarding a backlog of replies until the line is quiet",
}


class _Tick(NamedTuple):
    """One control tick: the step's time and output, and what failed."""

    t: float  # when the controller stepped (hub time)
    out: ControlOutput
    poll_started: float | None = None  # None: no poll (no link, or released while the tick waited)
    poll_error: Exception | None = None
    send_error: Exception | None = None


class _Flown(NamedTuple):
    """How a link's flight ended, as the serial thread hands it back to the loop: the next due time, what failed."""

    due: float
    poll_error: Exception | None = None
    send_error: Exception | None = None


def _close_quietly(link: ByteLink) -> None:
    """Serial-thread job: close the port; one that is already gone cannot fail the caller."""
    with suppress(OSError):
        link.close()


def _neutral_then_close(client: MspClient) -> None:
    """Serial-thread job, a link's last: neutral through the client, then close, so nothing can follow the neutral."""
    try:
        client.send_neutral()
        _drain(client.link, NEUTRAL_DRAIN_S)
    finally:
        _close_quietly(client.link)


def _drain(link: ByteLink, seconds: float) -> None:
    """Read and drop what the board sends for ``seconds`` (its replies, the neutral's acknowledgement).

    A TCP link (pyserial's ``socket://``) closed with unread bytes is reset, not ended, and the board's side then drops
    what it had not read yet: under load the board got a motor command as its last and never the neutral written after
    it (tests/daemon/test_signals.py, once in CI, session 24). Read until then, the link ends cleanly."""
    deadline = time.monotonic() + seconds
    with suppress(OSError, ValueError):
        while time.monotonic() < deadline:
            waiting = link.in_waiting
            if waiting:
                link.read(waiting)
            else:
                time.sleep(0.005)


class LinkOpener(Protocol):
    """Opens the byte link to a motor board: a serial port, or the simulated board."""

    description: str

    def open(self) -> ByteLink: ...


class SerialOpener:
    def __init__(self, port: str, baudrate: int, timeout_s: float) -> None:
        self.port, self.baudrate, self.timeout_s = port, baudrate, timeout_s
        self.description = f"serial {port} @ {baudrate}"

    def open(self) -> ByteLink:
        return open_serial(self.port, self.baudrate, self.timeout_s)


class SimOpener:
    """The simulated board on the hub's clock; one board for the daemon's life, reconnects reuse it.

    The board is powered up when the link first opens, not when the daemon is assembled: a real
    blimp is held at its start altitude until its controller runs, and a slow daemon start must
    not let the simulated one float to the ceiling first.
    """

    def __init__(self, config: FlightConfig, seed: int, clock: Callable[[], float]) -> None:
        from feelium.flight.blimp_model import DraftParams
        from feelium.flight.sim_board import BoardParams, SensorParams, board_with

        self.params = board_with(
            BoardParams(
                drafts=DraftParams() if config.sim.drafts else None,
                sensors=SensorParams(range_dropout_probability=config.sim.rangefinder_dropout),
            ),
            z=config.sim.start_altitude_m,
        )
        self.seed = seed
        self.clock = clock
        self.board: SimMotorBoard | None = None
        self.description = "simulated motor board (blimp simulator)"

    def open(self) -> ByteLink:
        from feelium.flight.sim_board import SimMotorBoard, SimSerial

        if self.board is None:
            self.board = SimMotorBoard(self.params, seed=self.seed, start_t=self.clock())
        return SimSerial(self.board, self.clock)


def resolve_backend(config: FlightConfig) -> str:
    """``auto``: the serial port when its device exists (or it is a URL), else the simulator."""
    if config.backend != "auto":
        return config.backend
    if "://" in config.port or os.path.exists(config.port):
        return "serial"
    return "sim"


class FlightService:
    """Closed-loop flight as a supervised daemon service."""

    name = "flight"
    stop_order = 0
    vital = True  # the supervisor feeds the systemd watchdog only while this loop's heartbeat is fresh

    def __init__(self, config: FlightConfig, hub: Hub, opener: LinkOpener) -> None:
        self.config = config
        self.hub = hub
        self.opener = opener
        self.controller = FlightController(config)
        self.soften = SoftenTracker(config.firm_touch_depth, config.soften_hold_s)
        self.link: ByteLink | None = None
        self.client: MspClient | None = None
        self.link_state = "down"
        self._up_since: float | None = None  # when a link last opened: its sensors are judged from a second after
        self.sensors = SensorWatch(config)
        self.altitude_watch = AltitudeWatch(config)
        self._logged_state: str | None = None
        self._link_logged_at: deque[float] = deque()  # hub times of the link lines of the last LINK_LOG_WINDOW_S
        self._link_changes_unlogged = 0
        self._past_counts = dict.fromkeys(LINK_COUNTERS, 0)
        self._telemetry_t: float | None = None
        self.stopping = False
        self.cycles = 0
        self.heartbeat_at: float | None = None  # hub time at the end of the newest control cycle
        self._rate = RateMeter()  # cycles flown with the board answering: decays when the loop or the link stalls
        self._rate_lock = threading.Lock()  # ticked on the serial thread, read by health() on the loop; both drop old ticks
        self.overruns = 0
        self.link_losses = 0
        self.reconnects = 0
        self.open_failures = 0
        self.bad_events = 0
        self.last_error: str | None = None
        self.last: ControlOutput | None = None
        self._next_open_t = float("-inf")
        self._backoff_s = min(config.reconnect_min_s, config.reconnect_max_s)
        self._serial: ThreadPoolExecutor | None = None
        self._wake = threading.Event()  # set when the link is released: a poll waiting for its tick is not made
        self._loop: asyncio.AbstractEventLoop | None = None  # run()'s loop, where the serial thread posts each tick's state
        self._unpublished: tuple[MspClient, ControlOutput] | None = None  # posted by the serial thread, not yet published
        self._unpublished_lock = threading.Lock()
        self._publish_due = False  # a wake-up of the loop for the unpublished tick is on its way
        self._posted_at, self._posted_link = float("-inf"), ""  # when the last wake-up was posted, the link state then
        # How late each tick runs against its due time: the poll's start and the controller's step, both on the
        # serial thread since the step moved there; what the event loop's load can delay is the start (docs/daemon.md).
        self.start_late = LatenessHistogram()
        self.step_late = LatenessHistogram()

    async def _on_serial_thread(self, call: Callable[..., Any], *args: Any) -> Any:
        """Run a port operation on this run's serial thread (jobs run one at a time, in order): an open, a close, a
        whole link's flight (:meth:`_fly`); its outcome comes back by one post to the loop (:func:`call_on`)."""
        assert self._serial is not None, "serial I/O outside run()"
        return await call_on(self._serial, call, *args)

    # ------------------------------------------------------------ lifecycle
    async def run(self) -> None:
        period = 1.0 / self.config.rate_hz
        events = self.hub.bus.subscribe(types=(TouchEvent, InteractionEvent), maxsize=64)
        serial = self._serial = ThreadPoolExecutor(max_workers=1, thread_name_prefix="flight-serial", initializer=name_current_thread)
        self._wake.clear()
        self._loop = asyncio.get_running_loop()
        try:
            due = self.hub.clock()
            while not self.stopping:
                if self.client is None:
                    due = await self._cycle_without_link(events, due, period)
                else:
                    due = await self._fly(events, due, period)
        finally:
            events.close()
            self._release()  # a crash or a cancel must not leave the last command on the motors
            serial.shutdown(wait=False)  # queued jobs (the neutral) still run; the thread then ends
            self._serial = None

    async def stop(self) -> None:
        """Motors to neutral now, through the MSP client; the loop commands nothing after this.

        ``stopping`` is set and the neutral queued before anything is awaited, so the loop cannot queue
        another serial job ahead of it: it runs right after whatever exchange is in flight. Waiting for it
        is bounded by ``STOP_WRITE_TIMEOUT_S``; the job is shielded, so a late board still gets it.
        """
        self.stopping = True
        job = self._release()
        if job is None:
            return
        try:
            await asyncio.wait_for(asyncio.shield(asyncio.wrap_future(job)), STOP_WRITE_TIMEOUT_S)
        except (OSError, ValueError, asyncio.TimeoutError) as exc:  # the board's watchdog stops them within 300 ms anyway
            self.last_error = f"stop: {exc!r}"

    def _release(self) -> Future[None] | None:
        """Detach the link (the loop sees none from now on); queue neutral-then-close as the serial thread's next job."""
        client, self.link, self.client = self.client, None, None
        self._wake.set()  # a poll waiting for its tick gives way at once: the neutral is the next thing written
        if client is None:
            return None
        self._retire(client)
        assert self._serial is not None, "a link outlived its run()"  # run() releases it before its thread goes
        return self._serial.submit(_neutral_then_close, client)

    def health(self) -> dict[str, Any]:
        out = self.last
        now = self.hub.clock()
        ages = self.controller.sensor_ages(now)
        report: dict[str, Any] = {
            **self._condition(now, ages),
            "backend": self.opener.description,
            "heartbeat_at": self.heartbeat_at,
            "link": self.link_state,
            "telemetry_age_s": self._telemetry_age_s(),
            **self._link_counts(),
            "cycles": self.cycles,
            "overruns": self.overruns,
            "tick_late_ms": {"start": self.start_late.snapshot(), "step": self.step_late.snapshot()},
            "link_losses": self.link_losses,
            "reconnects": self.reconnects,
            "open_failures": self.open_failures,
            "bad_events": self.bad_events,
            "mode": out.mode if out else None,
            "modes": dict(self.controller.mode_counts),
            "battery": out.battery if out else "unknown",
            "last_error": self.last_error,
            "fps": self._control_rate() if self.link_state == "up" else 0.0,
            "estimates": self.controller.estimates(now),
        }
        report["sensor_age_s"] = ages
        if self.client is not None:
            report["msp"] = self.client.health()
        board = getattr(self.opener, "board", None)
        if board is not None:
            report["sim_watchdog_trips"] = board.watchdog_trips
        return report

    def _telemetry_age_s(self) -> float | None:
        """How old the newest telemetry is: the live client's, which the serial thread renews every tick (the loop's
        copy follows the publications, up to ``PUBLISH_EVERY_S`` behind), else the last one a link had."""
        live = self.client
        newest = None if live is None else live.telemetry_t
        t = self._telemetry_t if newest is None else newest
        return None if t is None else round(self.hub.clock() - t, 3)

    def _control_rate(self) -> float:
        with self._rate_lock:
            return round(self._rate.rate(self.hub.clock()), 1)

    def _condition(self, now: float, ages: dict[str, float | None]) -> dict[str, str]:
        """The motor board link and its sensors as the part's health: without a board answering, with one whose sensors
        are silent (``ages``, at ``now``), or with the body outside its altitude limits, flight is not ok."""
        state = self.link_state
        stalled_s = None if self.heartbeat_at is None else now - self.heartbeat_at
        if stalled_s is not None and stalled_s > LOOP_STALL_S and not self.stopping:
            return {"condition": "degraded", "reason": f"control loop stalled: no cycle for {stalled_s:.1f} s"}
        if state == "up":
            up_for = 0.0 if self._up_since is None else now - self._up_since
            problems = (self.sensors.problems(now, ages, up_for, self.controller.surge.flow_noise_rad_s)
                        + self.altitude_watch.problems(now, self.controller.altitude.z,
                                                       held=self.last is not None and self.last.mode == "soft"))
            return {"condition": "degraded", "reason": "; ".join(problems)} if problems else {"condition": "ok"}
        if state in LINK_REASONS:
            return {"condition": "degraded", "reason": f"motor board link {state}: {LINK_REASONS[state]}"}
        if self.last_error is None:
            return {"condition": "starting", "reason": f"opening {self.opener.description}"}
        return {"condition": "failed", "reason": f"no motor board: {self.last_error}"}

    def _link_counts(self) -> dict[str, int]:
        """Stalls, resyncs and late replies of this service's life, the live client's included."""
        live = self.client
        return {name: self._past_counts[name] + (getattr(live, name) if live else 0) for name in LINK_COUNTERS}

    def _retire(self, client: MspClient) -> None:
        """Keep a dropped client's counts: each reconnect starts a fresh client."""
        for name in LINK_COUNTERS:
            self._past_counts[name] += getattr(client, name)

    def _set_link_state(self, state: str) -> None:
        """Record the link state; log the change into a bad state once (a failed reopen is no change), and the recovery.

        A link that flaps (a slow board resyncing every few ticks) would write several lines a second: at most
        ``LINK_LOG_BURST`` lines are written in any ``LINK_LOG_WINDOW_S`` (a stall, its resync and the recovery
        all show), the changes beyond are counted, and the next line written says how many there were. Health
        shows the state of every tick regardless."""
        if state == "up" and self.link_state not in ("up", "stalled", "resyncing"):  # a new link, not a resync's end
            self._up_since = self.hub.clock()
        self.link_state = state
        if state == "connecting" or state == self._logged_state:
            return
        previous, self._logged_state = self._logged_state, state
        now = self.hub.clock()
        logged = self._link_logged_at
        while logged and now - logged[0] >= LINK_LOG_WINDOW_S:
            logged.popleft()
        if len(logged) >= LINK_LOG_BURST:
            self._link_changes_unlogged += 1
            return
        logged.append(now)
        unlogged, self._link_changes_unlogged = self._link_changes_unlogged, 0
        flapped = f"; the link changed {unlogged} more times before this, not logged (flapping)" if unlogged else ""
        if state == "up":
            log.info("flight: motor board link up (was %s)%s", previous or "not yet open", flapped)
        elif state == "down":
            log.warning("flight: motor board link down: %s%s", self.last_error, flapped)
        else:
            log.warning("flight: motor board link %s (%s)%s", state, LINK_REASONS[state], flapped)

    # ------------------------------------------------------------ the cycles
    async def _cycle_without_link(self, events: Subscription[Any], due: float, period: float) -> float:
        """A cycle with no board to fly: sleep to ``due``, reopen the port when its backoff is over, else step.

        The controller steps on the loop without telemetry (it goes to its failsafe; the board's own watchdog
        stops the motors). A port that opens is flown from this same ``due``, so no tick is lost to the open.
        Returns the next cycle's due time.
        """
        await asyncio.sleep(max(0.0, due - self.hub.clock()))
        now = self.hub.clock()
        if now >= self._next_open_t and not self.stopping:
            await self._open(now)
            if self.client is not None:
                return due
        now = self.hub.clock()
        tick = _Tick(now, self._step(events, now, None))
        self._count(tick, due, link_up=False)
        self._publish(tick.out)
        return self._next_due(due, period)

    async def _fly(self, events: Subscription[Any], due: float, period: float) -> float:
        """Fly the open link until it fails or is released: one job of the serial thread, however many ticks.

        The thread keeps its own time (:meth:`_fly_ticks`), so how late the event loop runs (a burst of HTTP, a
        CPU quota) no longer delays the motors: the loop only publishes each tick's state, and takes up a lost
        link. Returns the next cycle's due time.
        """
        client = self.client
        assert client is not None
        flown = await self._on_serial_thread(self._fly_ticks, client, events, due, period)
        self._publish_posted()  # the last ticks, whose wake-up was not due yet
        error = flown.poll_error or (flown.send_error if client is self.client else None)  # one stop() released is no longer ours
        if error is not None:  # serial.SerialException is an OSError
            await self._lost(self.hub.clock(), error)
        return flown.due

    def _fly_ticks(self, client: MspClient, events: Subscription[Any], due: float, period: float) -> _Flown:
        """Serial-thread job: tick at ``period`` from ``due`` until the link fails or is released.

        Each tick's state goes to the loop by :meth:`_post`, which wakes the loop at most every
        ``PUBLISH_EVERY_S``, and at once when the link's state changes. A released link (stop(), the end of
        run(), a cancel) wakes the wait at once and ends the job, so the neutral queued behind it is the next
        thing on the port. So does an event loop that no longer runs (a blocked one still does): nothing could
        stop the motors or take up a lost link any more, and a job that flew on would keep the interpreter's exit
        waiting for this thread for ever; the board's watchdog sets neutral instead, and a loop that runs again
        flies the link again (:meth:`_fly`).
        """
        loop = self._loop
        assert loop is not None, "a flight outside run()"
        while True:
            battery = self.cycles % self.config.battery_every == 0
            tick = self._tick(client, events, due, battery)
            self._count(tick, due, link_up=client.state == "up")
            self._post(loop, client, tick.out, tick.t)
            due = self._next_due(due, period)
            if tick.poll_error is not None or tick.send_error is not None or client is not self.client or self.stopping:
                return _Flown(due, tick.poll_error, tick.send_error)
            if not loop.is_running():
                return _Flown(due)

    def _count(self, tick: _Tick, due: float, *, link_up: bool) -> None:
        """Record a tick: its lateness, its output, the heartbeat; the rate counts ticks flown with the board up."""
        self.start_late.record((tick.t if tick.poll_started is None else tick.poll_started) - due)
        self.step_late.record(tick.t - due)
        self.last = tick.out
        self.cycles += 1
        self.heartbeat_at = tick.t
        if link_up:
            with self._rate_lock:
                self._rate.tick(tick.t)

    def _next_due(self, due: float, period: float) -> float:
        """The next tick's due time; a tick that ran past it is an overrun, and the schedule restarts from now."""
        due += period
        now = self.hub.clock()
        if due < now:
            self.overruns += 1
            return now
        return due

    def _post(self, loop: asyncio.AbstractEventLoop, client: MspClient, out: ControlOutput, now: float) -> None:
        """Serial thread: hand a tick's state to the loop, waking it at most every ``PUBLISH_EVERY_S``.

        The newest tick always replaces one not yet published; the loop is woken for it when the last wake-up is
        ``PUBLISH_EVERY_S`` old or the link's state changed, so a stall or a resync shows at once. Nothing reads the
        published state faster (the headset's state replies, health): waking the loop 50 times a second for it
        was a tenth of its wake-ups.
        """
        with self._unpublished_lock:
            self._unpublished = (client, out)
            if self._publish_due or (now - self._posted_at < PUBLISH_EVERY_S and client.state == self._posted_link):
                return
            self._publish_due, self._posted_at, self._posted_link = True, now, client.state
        loop.call_soon_threadsafe(self._publish_posted)

    def _publish_posted(self) -> None:
        """Loop: publish the newest tick the serial thread posted, and the link state its client saw."""
        with self._unpublished_lock:
            posted, self._unpublished, self._publish_due = self._unpublished, None, False
        if posted is None:
            return
        client, out = posted
        self._observe_link(client)
        self._publish(out)

    def _tick(self, client: MspClient, events: Subscription[Any], due: float, with_battery: bool) -> _Tick:
        """Serial thread, one control tick: wait for ``due``, poll, step, command the motors at once.

        A released link (stop(), the end of run()) wakes the wait and is not polled, nor is it when the tick was
        already due and did not wait (a late thread): the step then has no
        telemetry and nothing is written, so the neutral queued behind this job is the next thing on the port.
        Nothing is written once ``stopping`` is set either; should stop() come between that check and the
        write, its neutral still follows the write, on this same thread. Errors are returned, not raised:
        the controller steps in every tick, and the loop takes up a lost link (:meth:`_fly`).
        """
        delay = due - self.hub.clock()
        telemetry, started, poll_error = None, None, None
        released = self._wake.wait(delay) if delay > 0.0 else self._wake.is_set()  # an overdue tick asks too
        if not released:
            started = self.hub.clock()
            try:
                telemetry = client.poll(with_battery)
            except (OSError, ValueError) as exc:
                poll_error = exc
        now = self.hub.clock()
        out = self._step(events, now, telemetry)
        send_error = None
        if poll_error is None and client is self.client and not self.stopping:
            try:
                client.send_motors(out.motors_us)
            except (OSError, ValueError) as exc:
                send_error = exc
        return _Tick(now, out, started, poll_error, send_error)

    def _step(self, events: Subscription[Any], now: float, telemetry: Telemetry | None) -> ControlOutput:
        """The controller's step at ``now`` with the events so far, the softening and the dead-man command.

        Runs on the serial thread with a link and on the loop without one, never on both at once (the loop
        awaits the thread's job): the soften tracker and the controller are only ever stepped by one of them.
        ``health()`` reads the controller's counters and estimates from the loop meanwhile: plain numbers,
        each whole, though one may be a tick newer than another.
        """
        for event in events.take():  # taken at the step: events that came while the tick waited count in it
            try:
                self.soften.observe(event, now)
            except (AttributeError, TypeError, ValueError):
                self.bad_events += 1
        soft = self.soften.active(now)
        command = self.hub.motion.active(now)
        setpoint = setpoint_for_motion(command.name if command else None, self.config, soften=soft)
        return self.controller.step(now, telemetry, setpoint)

    def _observe_link(self, client: MspClient) -> None:
        """After a poll: the client's view of the line becomes the link state, its newest telemetry the age.

        Not if stop() released that client while it polled: the link is no longer ours to describe.
        """
        if client is not self.client:
            return
        self._set_link_state(client.state)
        if client.telemetry_t is not None:
            self._telemetry_t = client.telemetry_t

    async def _open(self, now: float) -> None:
        self._set_link_state("connecting")
        try:
            link = await self._on_serial_thread(self.opener.open)
        except (OSError, ValueError) as exc:
            self.open_failures += 1
            self.last_error = f"open {self.opener.description}: {exc}"
            self._set_link_state("down")
            self._schedule_reopen(now)
            return
        if self.stopping:  # stop() came while the port was opening: leave it closed, command nothing
            await self._on_serial_thread(_close_quietly, link)
            return
        if self.link_losses:
            self.reconnects += 1
        self.link = link
        self.client = MspClient(link, timeout_s=self.config.reply_timeout_s, clock=self.hub.clock)
        self._set_link_state("up")
        self._backoff_s = min(self.config.reconnect_min_s, self.config.reconnect_max_s)

    async def _lost(self, now: float, exc: Exception) -> None:
        self.link_losses += 1
        self.last_error = f"link: {exc}"
        link, client, self.link, self.client = self.link, self.client, None, None
        if client is not None:
            self._retire(client)
        if link is not None:
            await self._on_serial_thread(_close_quietly, link)
        self._set_link_state("down")
        self._schedule_reopen(now)

    def _schedule_reopen(self, now: float) -> None:
        """The next attempt after the backoff, which doubles up to ``reconnect_max_s`` (under 1 s by default)."""
        self._next_open_t = now + self._backoff_s
        self._backoff_s = min(self._backoff_s * 2.0, self.config.reconnect_max_s)

    def _publish(self, out: ControlOutput) -> None:
        self.hub.state.update(
            "flight",
            altitude_m=None if out.altitude_m is None else round(out.altitude_m, 3),
            altitude_target_m=None if out.altitude_target_m is None else round(out.altitude_target_m, 3),
            heading_deg=out.heading_deg,
            heading_target_deg=None if out.heading_target_deg is None else round(out.heading_target_deg, 1),
            battery_v=out.battery_v,
            battery=out.battery,
            link=self.link_state,
            mode=out.mode,
            motors_us=list(out.motors_us),
        )
