"""The simulated board through the MSP client: the contract's commands, errors and the link watchdog."""

from __future__ import annotations

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
