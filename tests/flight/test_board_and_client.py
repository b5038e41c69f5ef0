"""The simulated board through the MSP client: the contract's commands, errors and the link watchdog."""

from __future__ import annotations

import copy
from dataclasses import replace

import pytest

from feelium.flight import messages as m
from feelium.flight.client import MspClient, MspErrorReply, MspTimeout
from feelium.flight.sim_board import BoardParams, SimMotorBoard, SimSerial
from feelium.flight.msp import MspParser, encode_v1, encode_v2
from feelium.lab.flight.simulation import ManualClock


def make() -> tuple[SimMotorBoard, MspClient, ManualClock]:
    clock = ManualClock()
    board = SimMotorBoard(BoardParams(), seed=3)
    return board, MspClient(SimSerial(board, clock), timeout_s=0.05, clock=clock), clock


def test_every_contract_command_answers() -> None:
    board, client, clock = make()
    assert client.api_version().major == 1
    assert client.rangefinder().distance_m == pytest.approx(1.0, abs=0.05)
    assert 0.0 <= client.attitude().heading_deg < 360.0
    assert client.altitude().altitude_m == pytest.approx(1.0, abs=0.5)
    assert client.analog().voltage_v > 4.0
    assert client.raw_imu().acc[2] == 512
    client.set_motors([1600, 1400, 1700, 1700])
    assert client.motors()[:4] == (1600, 1400, 1700, 1700)


def test_unknown_command_is_an_error_reply() -> None:
    _, client, _ = make()
    with pytest.raises(MspErrorReply):
        client.request(0x3000)


def test_v1_request_gets_a_v1_reply() -> None:
    board, _, clock = make()
    link = SimSerial(board, clock)
    link.write(encode_v1(m.MSP_API_VERSION))
    frames = MspParser().feed(link.read(64))
    assert frames[0].version == 1 and frames[0].payload == m.ApiVersion(0, 1, 46).encode()


def test_watchdog_neutralises_motors_300_ms_after_the_last_command() -> None:
    board, client, clock = make()
    client.set_motors([1800, 1800, 1800, 1800])
    clock.t = 0.25
    assert client.motors()[:4] == (1800,) * 4
    clock.t = 0.40
    assert client.motors()[:4] == (1500,) * 4
    assert board.watchdog_trips == 1


def test_refreshed_motors_stay_on() -> None:
    board, client, clock = make()
    for i in range(20):
        clock.t = i * 0.1
        client.send_motors([1700, 1700, 1700, 1700])
    assert client.motors()[:4] == (1700,) * 4 and board.watchdog_trips == 0


def test_garbage_and_corruption_on_the_line_are_survived() -> None:
    board, client, clock = make()
    link = client.link
    original_read = link.read
    noise = iter([b"\x00$M>\xff", b"$X>\x00\x6c\x00\x06\x00garbage", b""])

    def noisy_read(size: int = 1) -> bytes:
        extra = next(noise, b"")
        return extra + original_read(size)

    link.read = noisy_read  # type: ignore[method-assign]
    telemetry = client.poll(with_battery=True)
    assert telemetry.range_m is not None and telemetry.battery_v is not None
    counters = client.parser.counters
    assert counters.garbage_bytes + counters.bad_checksums + counters.oversized > 0


def test_no_answer_is_a_timeout_not_a_hang() -> None:
    import serial

    link = serial.serial_for_url("loop://", timeout=0.01)
    client = MspClient(link, timeout_s=0.05)
    with pytest.raises(MspTimeout):
        client.api_version()
    assert client.unexpected_replies >= 1  # loop:// echoes our own request
    assert client.timeouts == 1


def test_send_motors_ack_is_consumed_by_the_next_poll() -> None:
    _, client, clock = make()
    client.send_motors([1500] * 4)
    clock.t = 0.02
    client.poll()
    assert client.motor_acks == 1 and client.unexpected_replies == 0
    assert encode_v2(m.MSP_SET_MOTOR, m.encode_motors([1500] * 4))[:3] == b"$X<"



def _set(board: SimMotorBoard, motors: list[int]) -> None:
    board.handle(MspParser().feed(encode_v2(m.MSP_SET_MOTOR, m.encode_motors(motors), "<"))[0])


def test_a_command_acts_from_its_arrival_even_after_a_long_flight() -> None:
    """The board counts its physics steps: from 15.36 s on, in 2087 of the first 4500 ticks, an accumulated
    ``t += 0.005`` had drifted past its tolerance and left the tick's last step to run after the command,
    which then acted a step early (docs/calibrate-flight.md, session 15). A delayed
    board (``command_delay_s``, the phase sweep) acts part of a step later."""
    board = SimMotorBoard(BoardParams(), seed=3)
    t = 0.0
    while t < 15.4 - 1e-9:  # a 50 Hz control grid, neutral commands keeping the watchdog fed
        t = round(t + 0.02, 9)
        board.advance_to(t)
        _set(board, [1500, 1500, 1500, 1500])
    assert board.t == t  # every step up to the command's arrival has run
    idle, prompt, late = board, copy.deepcopy(board), copy.deepcopy(board)
    late.params = replace(late.params, command_delay_s=0.0025)
    before = board.state.thrust_n
    for commanded in (prompt, late):
        _set(commanded, [1500, 1500, 1100, 1100])
    for each in (idle, prompt, late):
        each.advance_to(round(t + 0.005, 9))
    fresh = SimMotorBoard(BoardParams(), seed=3)
    _set(fresh, [1500, 1500, 1100, 1100])
    fresh.advance_to(0.005)
    assert prompt.state.thrust_n[2] == pytest.approx(fresh.state.thrust_n[2], rel=1e-9)  # one step of it, not two
    assert prompt.state.thrust_n[2] < late.state.thrust_n[2] < idle.state.thrust_n[2] == before[2] == 0.0
