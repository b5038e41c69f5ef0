"""A misbehaving link: late replies are never used, a stalled board's backlog is resynchronised, drops reconnect.

Everything but the last test runs on a manual clock through :class:`FaultyLink` over the
simulated board, so each is deterministic and takes a fraction of a second; the last runs the
service itself on the wall clock (slow marker, like test_service.py).
"""

from __future__ import annotations

import asyncio
import logging
import random
import struct
from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from feelium.flight import messages as m
from feelium.flight.client import POLL_COMMANDS, MspClient
from feelium.flight.config import FlightConfig
from feelium.flight.faulty_link import FaultyLink, LinkFaults, Window
from feelium.flight.msp import MspFrame, MspParser, encode_v2
from feelium.flight.service import FlightService, SimOpener
from feelium.flight.sim_board import BoardParams, SensorParams, SimMotorBoard, SimSerial, board_with
from feelium.flight.telemetry import Telemetry
from feelium.hub import Hub
from feelium.lab.flight.simulation import ManualClock, SimFlight

from tests.flight.test_service import CONFIG as SERVICE_CONFIG
from tests.flight.test_service import wait_for

TIMEOUT_S = 0.03
PERIOD_S = 0.02
MAX_AGE_S = 0.1
CONFIG = FlightConfig()
NO_DROPOUTS = BoardParams(sensors=SensorParams(range_dropout_probability=0.0))


def rig(faults: LinkFaults = LinkFaults()) -> tuple[SimMotorBoard, FaultyLink, MspClient, ManualClock]:
    clock = ManualClock()
    board = SimMotorBoard(NO_DROPOUTS, seed=3)
    link = FaultyLink(SimSerial(board, clock), clock, faults, sleep=clock.sleep)
    return board, link, MspClient(link, timeout_s=TIMEOUT_S, clock=clock), clock


def fresh(telemetry: Telemetry) -> bool:
    return telemetry.range_m is not None and telemetry.heading_deg is not None


@dataclass
class Cycle:
    tick: float
    state_before: str
    returned_at: float
    telemetry: Telemetry
    waiting: int
    outstanding: int


@dataclass
class ControlLoop:
    """What the service does each period, on a fixed grid: advance the board, poll, command the motors."""

    board: SimMotorBoard
    link: FaultyLink
    client: MspClient
    clock: ManualClock
    cycles: list[Cycle] = field(default_factory=list)

    def run_until(self, t_end: float) -> None:
        tick = self.cycles[-1].tick if self.cycles else 0.0
        while True:
            tick = max(round(tick + PERIOD_S, 9), self.clock.t)
            if tick >= t_end - 1e-9:
                return
            self.clock.t = tick
            self.board.advance_to(tick)
            state = self.client.state
            telemetry = self.client.poll()
            outstanding = self.client.health()["outstanding"]
            self.cycles.append(Cycle(tick, state, self.clock.t, telemetry, self.link.in_waiting, outstanding))  # type: ignore[arg-type]
            self.client.send_motors(m.NEUTRAL_MOTORS_US)

    def between(self, start: float, end: float) -> list[Cycle]:
        return [c for c in self.cycles if start <= c.tick < end]


# ---------------------------------------------------------------- late replies
def test_a_board_lagging_past_the_timeout_gives_no_telemetry_and_its_late_replies_are_counted() -> None:
    board, link, client, clock = rig(LinkFaults(lag_s=0.04))
    loop = ControlLoop(board, link, client, clock)
    loop.run_until(0.3)
    assert all(not fresh(c.telemetry) for c in loop.cycles)  # every reply came after its burst's deadline
    assert all(c.telemetry.t <= c.returned_at <= c.telemetry.t + TIMEOUT_S + link.read_timeout_s for c in loop.cycles)
    assert client.late_replies > 0 and client.timeouts > 0
    assert client.telemetry_t is None and client.health()["telemetry_age_s"] is None


def test_a_late_reply_is_not_taken_for_the_next_burst_s() -> None:
    """The old client took the oldest reply per command: here that is the altitude before the jump."""
    board, link, client, clock = rig(LinkFaults(lag_s=0.04))
    assert not fresh(client.poll())  # burst 1 at t=0: its replies (z = 1 m) arrive at 0.04 s, after its deadline
    board.state = replace(board.state, z=2.0)
    link.faults = LinkFaults(lag_s=0.005)
    client.send_motors(m.NEUTRAL_MOTORS_US)  # the board now advances to 0.03 s: its range reading is 2 m
    clock.t = 0.035
    telemetry = client.poll()  # burst 2: burst 1's replies come first, then its own
    assert telemetry.t == 0.035 and clock.t - telemetry.t <= MAX_AGE_S
    assert telemetry.range_m == pytest.approx(2.0, abs=0.1)
    assert client.late_replies == len(POLL_COMMANDS)
    assert client.motor_acks == 1 and client.unexpected_replies == 0
    assert client.health()["outstanding"] == 0


def test_replies_within_the_timeout_are_fresh_and_stamped_with_their_burst() -> None:
    board, link, client, clock = rig(LinkFaults(lag_s=0.01))
    loop = ControlLoop(board, link, client, clock)
    loop.run_until(0.5)
    assert all(fresh(c.telemetry) and c.telemetry.t == c.tick for c in loop.cycles)
    assert client.late_replies == client.stale_bytes == client.resyncs == client.timeouts == 0
    assert client.motor_acks == len(loop.cycles) - 1  # the last one is still on its way


def test_a_request_swallowed_by_the_board_does_not_leave_every_later_reply_one_burst_behind() -> None:
    """Replies come in order, but a board may drop requests: then each reply would match the burst before."""
    board, link, client, clock = rig()
    loop = ControlLoop(board, link, client, clock)
    loop.run_until(0.1)
    inner_write = link.inner.write
    link.inner.write = lambda data: len(data)  # type: ignore[method-assign]  # the board misses one burst
    loop.run_until(0.12)
    link.inner.write = inner_write  # type: ignore[method-assign]
    loop.run_until(1.0)
    assert client.late_replies > 0 and client.lost_requests > 0
    recovered = [c for c in loop.between(0.12, 1.0) if fresh(c.telemetry)]
    assert recovered and recovered[0].tick < 0.12 + 0.1  # the next burst asks in another order: it shows at once
    assert all(fresh(c.telemetry) for c in loop.between(recovered[0].tick, 1.0))


# ---------------------------------------------------------------- stall, then flood
def test_a_stall_then_flood_is_resynchronised_within_a_second_and_leaves_no_backlog() -> None:
    stall = Window(1.0, 3.5)
    board, link, client, clock = rig(LinkFaults(stalls=(stall,)))
    loop = ControlLoop(board, link, client, clock)
    loop.run_until(stall.start_s)
    assert all(fresh(c.telemetry) for c in loop.cycles)
    loop.run_until(stall.end_s)
    held = MspParser().feed(bytes(link.held))
    assert client.stalled and client.stalls == 1
    assert client.timeouts == client.stall_bursts  # then it stopped asking: one small probe per cycle
    assert sum(f.command in POLL_COMMANDS for f in held) == client.stall_bursts * len(POLL_COMMANDS)
    stale_before = client.stale_bytes
    loop.run_until(stall.end_s + 2.0)

    after = loop.between(stall.end_s, stall.end_s + 2.0)
    first = next(c for c in after if fresh(c.telemetry))
    assert first.tick - stall.end_s < 1.0
    recovered = [c for c in after if c.tick >= first.tick]
    assert all(fresh(c.telemetry) and c.returned_at - c.telemetry.t <= MAX_AGE_S for c in recovered)
    assert all(c.waiting == 0 for c in recovered)  # the input buffer does not fill up
    assert client.stalls == 1 and client.resyncs == 1 and client.state == "up"
    assert client.stale_bytes - stale_before >= 9 * len(held)  # the whole flood was discarded, none of it used
    assert client.late_replies == 0  # it answered requests forgotten at the stall, so they were stale, not late
    assert client.health()["telemetry_age_s"] <= MAX_AGE_S


def test_while_stalled_or_resynchronising_poll_returns_at_once_with_no_fields() -> None:
    stall = Window(0.5, 1.0)
    board, link, client, clock = rig(LinkFaults(stalls=(stall,)))
    loop = ControlLoop(board, link, client, clock)
    loop.run_until(stall.end_s + 0.5)
    waiting = [c for c in loop.cycles if c.state_before != "up"]
    assert {c.state_before for c in waiting} == {"stalled", "resyncing"}
    held_back = [c for c in waiting if c.telemetry == Telemetry(t=c.tick)]
    assert held_back and all(c.returned_at == c.tick for c in held_back)  # no blocking at all
    assert len(waiting) - len(held_back) == 1  # the poll that found the line quiet again went on to a burst


def test_a_board_answering_half_a_second_late_is_resynchronised_not_followed() -> None:
    """Replies keep coming, half a second late: the outstanding requests stay bounded and none is used."""
    board, link, client, clock = rig(LinkFaults(lag_s=0.5))
    loop = ControlLoop(board, link, client, clock)
    loop.run_until(3.0)
    assert client.resyncs >= 2 and client.stalls >= 1
    assert max(c.outstanding for c in loop.cycles) <= client.max_outstanding
    assert all(not fresh(c.telemetry) for c in loop.cycles)
    assert max(c.waiting for c in loop.cycles) < 200


# ---------------------------------------------------------------- an oracle
class NumberedBoard(SimMotorBoard):
    """Answers the rangefinder with the number the request carries, so a reply shows which request it answers."""

    def handle(self, frame: MspFrame) -> bytes:
        if frame.command == m.MSP_SONAR_ALTITUDE and len(frame.payload) == 4:
            (number,) = struct.unpack("<I", frame.payload)
            return encode_v2(frame.command, m.Rangefinder(number / 100).encode(), ">")
        return super().handle(frame)


class Numbering:
    """Between client and link: numbers each rangefinder request as it is written."""

    def __init__(self, link: FaultyLink) -> None:
        self.link = link
        self.written = 0
        self._parser = MspParser()

    @property
    def in_waiting(self) -> int:
        return self.link.in_waiting

    def write(self, data: bytes) -> int:
        out = bytearray()
        for frame in self._parser.feed(data):
            payload = frame.payload
            if frame.command == m.MSP_SONAR_ALTITUDE:
                self.written += 1
                payload = struct.pack("<I", self.written)
            out += encode_v2(frame.command, payload)
        return self.link.write(bytes(out))

    def read(self, size: int = 1) -> bytes:
        return self.link.read(size)

    def close(self) -> None:
        self.link.close()


@pytest.mark.parametrize("seed", range(3))
def test_under_random_stalls_lags_swallowed_requests_and_noise_no_reply_is_taken_for_another_burst_s(seed: int) -> None:
    """Each fresh rangefinder reading must answer the rangefinder request of the burst that returned it."""
    rnd = random.Random(seed)
    clock = ManualClock()
    board = NumberedBoard(NO_DROPOUTS, seed=3)
    inner = SimSerial(board, clock)
    deliver = inner.write
    inner.write = lambda data: len(data) if rnd.random() < 0.01 else deliver(data)  # type: ignore[method-assign]
    stalls = (Window(1.0, 1.4), Window(2.5, 4.0), Window(5.0, 5.1), Window(6.5, 7.5))
    link = FaultyLink(inner, clock, LinkFaults(stalls=stalls), sleep=clock.sleep)
    numbering = Numbering(link)
    client = MspClient(numbering, timeout_s=TIMEOUT_S, clock=clock)
    tick, fresh_polls, polls = 0.0, 0, 0
    while tick < 10.0:
        tick = max(round(tick + PERIOD_S, 9), clock.t)
        clock.t = tick
        if rnd.random() < 0.03:
            link.faults = replace(link.faults, lag_s=rnd.choice([0.0, 0.01, 0.025, 0.04, 0.1, 0.3]))
        if rnd.random() < 0.01:
            link.inject(rnd.choice([b"\x00\xff", b"$X>\x00\x3a", b"$M>\x04\x3a\x01"]))
        board.advance_to(tick)
        telemetry = client.poll(with_battery=polls % 25 == 0)
        polls += 1
        if telemetry.range_m is not None:
            fresh_polls += 1
            assert round(telemetry.range_m * 100) == numbering.written, f"a reply to another burst at {tick:.3f} s"
            assert clock.t - telemetry.t <= MAX_AGE_S
        client.send_motors(m.NEUTRAL_MOTORS_US)
    assert fresh_polls > polls // 5 and client.resyncs > 0 and client.stalls > 0


# ---------------------------------------------------------------- noise on the line
def test_garbage_and_truncated_frames_between_bursts_are_survived() -> None:
    board, link, client, clock = rig()
    loop = ControlLoop(board, link, client, clock)
    loop.run_until(0.2)
    truncated = encode_v2(m.MSP_ATTITUDE, m.Attitude(0.0, 0.0, 10.0).encode(), ">")[:7]
    link.inject(b"\x00\xffnoise$M>\xff" + truncated)
    loop.run_until(0.8)
    counters = client.parser.counters
    assert counters.garbage_bytes + counters.bad_checksums + counters.truncated > 0
    assert client.stale_bytes > 0
    assert all(fresh(c.telemetry) for c in loop.between(0.3, 0.8))
    assert all(abs(c.telemetry.heading_deg - 10.0) > 1.0 for c in loop.cycles)  # the fragment's heading was never used


# ---------------------------------------------------------------- closed loop
def hover(faults: LinkFaults) -> SimFlight:
    return SimFlight(CONFIG, board_with(BoardParams(), z=1.2), faults=faults)


def first_fresh_after(flight: SimFlight, t: float, until: float) -> float:
    while flight.t < until:
        flight.step()
        if flight.client.telemetry_t is not None and flight.client.telemetry_t >= t:
            return flight.t
    raise AssertionError("no fresh telemetry")


def test_a_stall_in_flight_is_followed_by_fresh_telemetry_within_a_second() -> None:
    stall = Window(6.0, 8.5)
    flight = hover(LinkFaults(stalls=(stall,)))
    flight.run(stall.end_s)
    assert flight.board.watchdog_trips == 1  # the board's physics and watchdog ran on through the stall
    assert first_fresh_after(flight, stall.end_s, stall.end_s + 2.0) - stall.end_s < 1.0
    flight.run(1.0)
    assert flight.client.state == "up" and flight.client.stalls == 1 and flight.client.resyncs == 1


@pytest.mark.xfail(
    reason="physics, not the link: a frozen board's watchdog stops the motors and the positively buoyant body "
    "rises 1.3 m during a 2.5 s stall, reaching 1.0 m/s as the stall ends; the full down-thrust then needs about "
    "0.5 m to stop it, so no controller on the Pi can keep it within 30 cm (measured 0.56 m, to the 3 m ceiling; "
    "it is back inside altitude_max 6 s later). Meeting this goal needs a board whose watchdog holds the last "
    "vertical command briefly rather than neutral, a change to the contract (docs/motor-board.md), not to the Pi",
    strict=False,
)
def test_after_a_stall_in_hover_the_altitude_moves_less_than_30_cm() -> None:
    stall = Window(6.0, 8.5)
    flight = hover(LinkFaults(stalls=(stall,)))
    flight.run(stall.end_s + 6.0)
    z = flight.log["z"][flight.log["t"] >= stall.end_s]
    assert np.ptp(z) < 0.30


def test_a_dropped_link_is_reopened_within_a_second_of_its_return_and_the_blimp_ends_in_its_altitude_band() -> None:
    drop = Window(6.0, 9.0)
    flight = hover(LinkFaults(drops=(drop,)))
    flight.run(drop.end_s)
    assert flight.link_losses == 1 and not flight.connected
    assert flight.last is not None and flight.last.mode == "telemetry_failsafe"
    assert first_fresh_after(flight, drop.end_s, drop.end_s + 2.0) - drop.end_s < 1.0
    assert len(flight.reconnect_times) == 1 and drop.end_s <= flight.reconnect_times[0] < drop.end_s + 1.0
    flight.run(12.0)
    assert flight.last.mode == "flying"
    assert CONFIG.altitude_min_m - 0.1 <= flight.board.state.z <= CONFIG.altitude_max_m + 0.1


def test_fault_free_flights_are_unchanged_by_an_empty_fault_schedule() -> None:
    plain = SimFlight(CONFIG, board_with(BoardParams(), z=1.2))
    wrapped = hover(LinkFaults())
    plain.run(3.0)
    wrapped.run(3.0)
    assert np.array_equal(plain.log["z"], wrapped.log["z"]) and np.array_equal(plain.log["m3"], wrapped.log["m3"])


# ---------------------------------------------------------------- the service
class FaultySimOpener(SimOpener):
    """The sim backend behind a faulty link (on the hub's clock), so a test can stall it."""

    def __init__(self, *args: object) -> None:
        super().__init__(*args)  # type: ignore[arg-type]
        self.links: list[FaultyLink] = []

    def open(self) -> FaultyLink:
        link = FaultyLink(super().open(), self.clock)
        self.links.append(link)
        return link


@pytest.mark.slow
async def test_the_service_logs_each_link_state_change_once_and_reports_the_stall_in_health(caplog: pytest.LogCaptureFixture) -> None:
    hub = Hub()
    opener = FaultySimOpener(SERVICE_CONFIG, 1, hub.clock)
    service = FlightService(SERVICE_CONFIG, hub, opener)
    task = asyncio.create_task(service.run())
    try:
        await wait_for(lambda: service.cycles > 10 and service.link_state == "up")
        assert 0.0 <= service.health()["telemetry_age_s"] <= MAX_AGE_S
        caplog.set_level(logging.INFO, logger="feelium.flight.service")
        caplog.clear()  # only what the stall causes: the start-up "link up" may or may not have been captured
        now = hub.clock()
        opener.links[-1].faults = LinkFaults(stalls=(Window(now, now + 0.5),))
        await wait_for(lambda: service.link_state == "stalled", timeout_s=2.0)
        assert service.health()["fps"] == 0.0
        await wait_for(lambda: service.link_state == "up" and hub.clock() > now + 0.5, timeout_s=3.0)
        health = service.health()
        assert health["link"] == "up" and health["stalls"] == 1 and health["resyncs"] == 1
        assert health["late_replies"] == 0 and health["telemetry_age_s"] <= MAX_AGE_S
        assert health["msp"]["stale_bytes"] > 0 and health["link_losses"] == 0
        messages = [(r.levelno, r.getMessage()) for r in caplog.records if r.name == "feelium.flight.service"]
        assert [level for level, _ in messages] == [logging.WARNING, logging.WARNING, logging.INFO], messages
        assert "link stalled" in messages[0][1] and "link resyncing" in messages[1][1]  # the backlog that came back
        assert "link up (was resyncing)" in messages[2][1]
    finally:
        await service.stop()
        await asyncio.wait_for(task, 2.0)


def test_a_flapping_link_writes_a_few_lines_then_counts_the_rest_into_the_next(caplog: pytest.LogCaptureFixture) -> None:
    """A slow board resyncing every ~120 ms wrote 8 lines in 0.5 s (R15b F3): the log stays readable, nothing is hidden."""
    hub = Hub()
    now = [100.0]
    hub.clock = lambda: now[0]
    service = FlightService(SERVICE_CONFIG, hub, SimOpener(SERVICE_CONFIG, 1, hub.clock))
    caplog.set_level(logging.INFO, logger="feelium.flight.service")
    for i in range(20):  # 20 changes in 2.4 s
        service._set_link_state("resyncing" if i % 2 else "up")
        now[0] += 0.12
    assert service.link_state == "resyncing"  # the state itself follows every change (the 20th)
    lines = [r.getMessage() for r in caplog.records if r.name == "feelium.flight.service"]
    assert len(lines) == 4 and "link up" in lines[0] and "link resyncing" in lines[1]
    now[0] = 100.0 + 10.5  # the window has passed
    service._set_link_state("stalled")
    last = [r.getMessage() for r in caplog.records if r.name == "feelium.flight.service"][-1]
    assert "link stalled" in last and "changed 16 more times before this" in last
