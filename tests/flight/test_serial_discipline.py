"""One owner per flight concept: neutral is defined once, stop goes through the MSP client, the port has one thread.

Runs the real service against the simulated board on the wall clock (slow marker, like test_service.py).
"""

from __future__ import annotations

import asyncio
import threading

import pytest

from feelium.flight import messages as m
from feelium.flight.sim_board import SimSerial
from feelium.flight.mixer import NEUTRAL, to_microseconds
from feelium.flight.msp import MspParser
from feelium.flight.service import FlightService, SimOpener
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


def test_neutral_has_one_definition_that_the_mixer_and_client_agree_with():
    assert m.NEUTRAL_MOTORS_US == (m.MOTOR_NEUTRAL_US,) * 4
    assert to_microseconds(NEUTRAL) == m.NEUTRAL_MOTORS_US


async def test_every_serial_call_runs_on_one_thread_and_stop_sends_neutral_last() -> None:
    hub = Hub()
    opener = RecordingOpener(CONFIG, 1, hub.clock)
    service = FlightService(CONFIG, hub, opener)
    task = asyncio.create_task(service.run())
    hub.motion.command("forward", now=hub.clock(), hold_s=2.0)  # motors busy, not neutral
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
