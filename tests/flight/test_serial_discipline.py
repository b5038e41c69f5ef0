"""One owner per flight concept: neutral is defined once, stop goes through the MSP client, the port has one thread.

Runs the real service against the simulated board on the wall clock (slow marker, like test_service.py).
"""

from __future__ import annotations

import ast
import asyncio
import threading
import time
from collections import deque
from pathlib import Path

import pytest

from feelium.flight import messages as m
from feelium.flight import service as service_module
from feelium.flight.client import MspClient
from feelium.flight.controller import ControlOutput, FlightController
from feelium.flight.sim_board import SimSerial
from feelium.flight.mixer import NEUTRAL, to_microseconds
from feelium.flight.msp import MspFrame, MspParser
from feelium.flight.replies import Outstanding
from feelium.flight.service import STOP_WRITE_TIMEOUT_S, FlightService, SimOpener
from feelium.flight.setpoint import setpoint_for_motion
from feelium.hub import Hub

from tests.flight.test_service import CONFIG, wait_for

pytestmark = pytest.mark.slow


class ThreadRecordingSerial:
    """Wraps the emulated serial link: records the thread of every call and every byte written."""

    def __init__(self, inner: SimSerial) -> None:
        self.inner = inner
        self.threads: set[int] = set()
        self.written = bytearray()
        self.closed_at_bytes: int | None = None
        self.writes_after_close = 0
        self.stall_s = 0.0  # the next read blocks this long, like a board that answers late
        self.stalled = threading.Event()

    def _mark(self) -> None:
        self.threads.add(threading.get_ident())

    def write(self, data: bytes) -> int:
        self._mark()
        if self.closed_at_bytes is not None:
            self.writes_after_close += 1
        self.written += data
        return self.inner.write(data)

    def read(self, size: int = 1) -> bytes:
        self._mark()
        if self.stall_s:
            stall_s, self.stall_s = self.stall_s, 0.0
            self.stalled.set()
            time.sleep(stall_s)
        return self.inner.read(size)

    @property
    def in_waiting(self) -> int:
        self._mark()
        return self.inner.in_waiting

    def close(self) -> None:
        self._mark()
        self.closed_at_bytes = len(self.written)
        self.inner.close()


class RecordingOpener(SimOpener):
    def __init__(self, *args: object) -> None:
        super().__init__(*args)  # type: ignore[arg-type]
        self.opened_on: set[int] = set()
        self.links: list[ThreadRecordingSerial] = []

    def open(self) -> ThreadRecordingSerial:  # type: ignore[override]
        self.opened_on.add(threading.get_ident())
        link = ThreadRecordingSerial(super().open())  # type: ignore[arg-type]
        self.links.append(link)
        return link


def serial_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("flight-serial")]


def requests_in(written: bytes | bytearray) -> list[MspFrame]:
    """The MSP requests the Pi wrote, in order (replies never travel this way)."""
    return [f for f in MspParser().feed(bytes(written)) if f.direction == "<"]


def is_neutral(frame: MspFrame) -> bool:
    return frame.command == m.MSP_SET_MOTOR and m.decode_motors(frame.payload)[:4] == m.NEUTRAL_MOTORS_US


def test_neutral_has_one_definition_that_the_mixer_and_client_agree_with() -> None:
    assert m.NEUTRAL_MOTORS_US == (m.MOTOR_NEUTRAL_US,) * 4
    assert to_microseconds(NEUTRAL) == m.NEUTRAL_MOTORS_US
    assert not hasattr(service_module, "NEUTRAL_US")
    waiting = FlightController(CONFIG).step(0.0, None, setpoint_for_motion(None, CONFIG))
    assert waiting.mode == "waiting" and waiting.commands == NEUTRAL and waiting.motors_us == m.NEUTRAL_MOTORS_US


def test_the_neutral_microseconds_are_written_down_only_in_messages() -> None:
    """Every other flight module derives neutral from ``messages``; a second literal 1500 would be a second definition."""
    root = Path(service_module.__file__).resolve().parents[1]
    holders = {
        path.relative_to(root).as_posix()
        for folder in (root / "flight", root / "lab" / "flight")
        for path in folder.glob("*.py")
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.Constant) and type(node.value) in (int, float) and node.value == m.MOTOR_NEUTRAL_US
    }
    assert holders == {"flight/messages.py"}


async def test_every_serial_call_runs_on_one_thread_and_stop_sends_neutral_last() -> None:
    hub = Hub()
    opener = RecordingOpener(CONFIG, 1, hub.clock)
    service = FlightService(CONFIG, hub, opener)
    task = asyncio.create_task(service.run())
    hub.motion.command("forward", now=hub.clock(), hold_s=0.5)  # motors busy, not neutral
    await wait_for(lambda: service.cycles > 30)
    await service.stop()
    await asyncio.wait_for(task, 2.0)
    (link,) = opener.links
    assert len(link.threads | opener.opened_on) == 1, "the port was used from more than one thread"
    assert threading.get_ident() not in link.threads  # never the event loop's thread
    assert link.closed_at_bytes is not None and link.writes_after_close == 0
    requests = [f for f in MspParser().feed(bytes(link.written)) if f.direction == "<"]
    motor_frames = [f for f in requests if f.command == m.MSP_SET_MOTOR]
    assert requests[-1].command == m.MSP_SET_MOTOR, "something was written after the stop's neutral"
    assert m.decode_motors(motor_frames[-1].payload)[:4] == m.NEUTRAL_MOTORS_US
    assert any(m.decode_motors(f.payload)[:4] != m.NEUTRAL_MOTORS_US for f in motor_frames[:-1])  # it was flying
    assert service.client is None and service.link is None


async def test_stop_during_a_stalled_exchange_is_the_next_serial_job_and_is_never_dropped(monkeypatch: pytest.MonkeyPatch) -> None:
    """The board answers late (longer than stop() may wait): neutral still goes out, right after that exchange, last."""
    sent_neutral_on: list[int] = []
    send_neutral = MspClient.send_neutral

    def recording_send_neutral(client: MspClient) -> None:
        sent_neutral_on.append(threading.get_ident())
        send_neutral(client)

    monkeypatch.setattr(MspClient, "send_neutral", recording_send_neutral)
    hub = Hub()
    opener = RecordingOpener(CONFIG, 1, hub.clock)
    service = FlightService(CONFIG, hub, opener)
    task = asyncio.create_task(service.run())
    hub.motion.command("forward", now=hub.clock(), hold_s=0.5)
    await wait_for(lambda: service.cycles > 30)
    (link,) = opener.links
    link.stall_s = 2 * STOP_WRITE_TIMEOUT_S
    await wait_for(link.stalled.is_set, timeout_s=2.0)  # the serial thread is now inside a poll's read
    written_before_stop = len(link.written)
    loop = asyncio.get_running_loop()
    started_at = loop.time()
    await service.stop()
    assert loop.time() - started_at < STOP_WRITE_TIMEOUT_S + 0.15  # stop() keeps its bound...
    assert "stop" in (service.last_error or "")
    await asyncio.wait_for(task, 2.0)
    await wait_for(lambda: link.closed_at_bytes is not None, timeout_s=2.0)  # ...and the neutral still lands
    assert len(sent_neutral_on) == 1 and set(sent_neutral_on) == link.threads
    after_stop = requests_in(link.written[written_before_stop:])
    assert len(after_stop) == 1 and is_neutral(after_stop[0]), "the loop commanded something after stop()"
    assert link.writes_after_close == 0
    assert opener.board is not None and opener.board.motors_us == m.NEUTRAL_MOTORS_US
    await wait_for(lambda: not serial_threads(), timeout_s=2.0)


async def test_a_crashed_run_leaves_motors_neutral_and_ends_its_thread_and_a_restart_flies_again() -> None:
    hub = Hub()
    opener = RecordingOpener(CONFIG, 1, hub.clock)
    service = FlightService(CONFIG, hub, opener)
    step = service.controller.step

    def crashing_step(*args: object) -> ControlOutput:
        if service.cycles >= 20:
            raise RuntimeError("controller bug")
        return step(*args)  # type: ignore[arg-type]

    service.controller.step = crashing_step  # type: ignore[method-assign]
    hub.motion.command("forward", now=hub.clock(), hold_s=0.5)
    with pytest.raises(RuntimeError, match="controller bug"):
        await asyncio.wait_for(service.run(), 5.0)
    crashed = opener.links[0]
    await wait_for(lambda: crashed.closed_at_bytes is not None, timeout_s=2.0)
    assert is_neutral(requests_in(crashed.written)[-1]) and crashed.writes_after_close == 0
    assert len(crashed.threads | opener.opened_on) == 1
    await wait_for(lambda: not serial_threads(), timeout_s=2.0)

    service.controller.step = step  # type: ignore[method-assign]
    opener.opened_on.clear()
    task = asyncio.create_task(service.run())  # what the supervisor does after its backoff
    await wait_for(lambda: service.cycles > 40)
    await service.stop()
    await asyncio.wait_for(task, 2.0)
    restarted = opener.links[1]
    assert len(restarted.threads | opener.opened_on) == 1
    assert is_neutral(requests_in(restarted.written)[-1]) and restarted.closed_at_bytes is not None


async def test_a_stop_before_an_overdue_tick_is_not_answered_with_a_poll_of_the_released_link() -> None:
    """stop() releases the link just before a tick that is already due (a loaded machine: the thread runs late).

    The tick must see the release and go without polling, so the neutral is the next thing on the port: a poll of
    the released link would put a whole exchange (up to the reply timeout, longer on a board that answers late)
    between stop() and its neutral.
    """
    hub = Hub()
    opener = RecordingOpener(CONFIG, 1, hub.clock)
    service = FlightService(CONFIG, hub, opener)
    fly_ticks = service._fly_ticks
    entered, gate = threading.Event(), threading.Event()

    def late_fly_ticks(*args: object) -> object:  # the serial thread gets to the job late
        entered.set()
        gate.wait(5.0)
        return fly_ticks(*args)  # type: ignore[arg-type]

    service._fly_ticks = late_fly_ticks  # type: ignore[method-assign]
    task = asyncio.create_task(service.run())
    try:
        await wait_for(entered.is_set)
        (link,) = opener.links
        written_before_stop = len(link.written)
        stopping = asyncio.create_task(service.stop())
        await asyncio.sleep(0)  # stop() has released the link and queued its neutral
        assert service.client is None
        await asyncio.sleep(3.0 / CONFIG.rate_hz)  # the job's first tick is now overdue
    finally:
        gate.set()
    await stopping
    await asyncio.wait_for(task, 2.0)
    after_stop = requests_in(link.written[written_before_stop:])
    assert [f.command for f in after_stop] == [m.MSP_SET_MOTOR] and is_neutral(after_stop[0]), "the released link was polled"


class TakenJustBeforeTheRead(deque):  # type: ignore[type-arg]
    """Outstanding requests as the loop's health() sees them while the serial thread takes the last one's reply:
    counted, then gone by the time one is read (the thread ran in between)."""

    def __getitem__(self, index: int) -> Outstanding:  # type: ignore[override]
        self.clear()
        return super().__getitem__(index)


def test_the_client_health_read_on_the_loop_survives_the_serial_thread_taking_the_last_reply_meanwhile() -> None:
    """health() never raises (feelium/service.py); the supervisor feeds systemd's watchdog only on a health() that
    shows the flight heartbeat, so a race with the serial thread must not make it raise."""
    client = MspClient(SimOpener(CONFIG, 1, time.monotonic).open(), clock=time.monotonic)
    client._outstanding = TakenJustBeforeTheRead([Outstanding(m.MSP_ATTITUDE, time.monotonic(), 1)])
    health = client.health()
    assert health["outstanding"] == 1 and health["oldest_outstanding_s"] is None


def test_an_event_loop_stopped_under_a_running_flight_does_not_leave_its_thread_flying() -> None:
    """A loop that stops with run() still pending (run_until_complete of something else, then the program ends):
    nothing on it can stop the motors, take up a lost link or publish any more. The link's job must end, or it
    flies on for ever and the interpreter's exit, which joins the serial thread, hangs with the motors still
    commanded. Ended, the board's watchdog sets them neutral (docs/motor-board.md), as after any end of the Pi's side.
    A loop that is running but blocked is another matter: flight goes on (test_service.py).
    """
    loop = asyncio.new_event_loop()
    hub = Hub()
    opener = RecordingOpener(CONFIG, 1, hub.clock)
    service = FlightService(CONFIG, hub, opener)
    task = loop.create_task(service.run())
    try:
        loop.run_until_complete(wait_for(lambda: service.cycles > 10))  # then the loop stops, run() pending
        (link,) = opener.links
        deadline = time.monotonic() + 5.0
        while True:
            written = len(link.written)
            time.sleep(0.5)  # 25 periods
            if len(link.written) == written:
                break
            assert time.monotonic() < deadline, "the serial thread flies on under a stopped event loop"
    finally:
        task.cancel()
        loop.run_until_complete(asyncio.gather(task, return_exceptions=True))
        loop.close()
    deadline = time.monotonic() + 5.0
    while link.closed_at_bytes is None and time.monotonic() < deadline:  # the end of run(): neutral, then close
        time.sleep(0.02)
    assert is_neutral(requests_in(link.written)[-1]) and link.closed_at_bytes is not None
