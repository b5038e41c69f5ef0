"""MSP framing: known vectors, round trips, and a parser that survives anything."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.flight import messages as m
from feelium.flight.msp import MspFrame, MspParser, _crc8_dvb_s2_bitwise, crc8_dvb_s2, encode_v1, encode_v2


def test_crc8_dvb_s2_known_vector() -> None:
    # Standard check value of CRC-8/DVB-S2 over the ASCII digits 1..9.
    assert crc8_dvb_s2(b"123456789") == 0xBC


@given(data=st.binary(max_size=80), start=st.integers(0, 255))
def test_the_table_crc_is_the_bitwise_definition(data: bytes, start: int) -> None:
    assert crc8_dvb_s2(data, start) == _crc8_dvb_s2_bitwise(data, start)
    assert crc8_dvb_s2(bytearray(data), start) == _crc8_dvb_s2_bitwise(data, start)


def test_a_request_without_payload_is_the_same_frame_each_time_and_a_bad_command_still_raises() -> None:
    first = encode_v2(m.MSP_ATTITUDE)
    assert encode_v2(m.MSP_ATTITUDE) is first  # built once
    assert first == b"$X<\x00" + bytes([m.MSP_ATTITUDE, 0, 0, 0]) + bytes([crc8_dvb_s2(first[3:8])])
    assert encode_v2(m.MSP_ATTITUDE, direction=">") != first
    for _ in range(2):
        try:
            encode_v2(0x10000)
        except ValueError:
            continue
        raise AssertionError("a command above 65535 must raise")


def test_v1_request_bytes_match_the_classic_attitude_request() -> None:
    assert encode_v1(m.MSP_ATTITUDE) == b"$M<\x00\x6c\x6c"


def test_v2_frame_layout() -> None:
    frame = encode_v2(m.MSP_SET_MOTOR, b"\x01\x02")
    assert frame[:3] == b"$X<"
    assert frame[3] == 0 and frame[4:6] == bytes([214, 0]) and frame[6:8] == bytes([2, 0])
    assert frame[8:10] == b"\x01\x02" and frame[10] == crc8_dvb_s2(frame[3:10])


@given(
    command=st.integers(0, 0xFFFF),
    payload=st.binary(max_size=64),
    direction=st.sampled_from(["<", ">", "!"]),
)
def test_v2_round_trip(command: int, payload: bytes, direction: str) -> None:
    parser = MspParser()
    assert parser.feed(encode_v2(command, payload, direction)) == [MspFrame(2, direction, command, payload)]


@given(command=st.integers(0, 254), payload=st.binary(max_size=64), direction=st.sampled_from(["<", ">", "!"]))
def test_v1_round_trip(command: int, payload: bytes, direction: str) -> None:
    assert MspParser().feed(encode_v1(command, payload, direction)) == [MspFrame(1, direction, command, payload)]


frames_strategy = st.lists(
    st.tuples(st.integers(0, 254), st.binary(max_size=24), st.booleans()), min_size=1, max_size=8
)


@settings(max_examples=200)
@given(frames=frames_strategy, garbage=st.lists(st.binary(max_size=12), min_size=9, max_size=9), cuts=st.randoms())
def test_parser_finds_every_frame_between_garbage_in_any_chunking(frames, garbage, cuts: random.Random) -> None:
    stream = bytearray()
    expected = []
    for i, (command, payload, v2) in enumerate(frames):
        # Garbage must not itself contain a valid frame; strip '$' so it cannot start one.
        stream += garbage[i].replace(b"$", b"")
        stream += encode_v2(command, payload, ">") if v2 else encode_v1(command, payload, ">")
        expected.append((command, payload))
    parser = MspParser()
    got = []
    pos = 0
    while pos < len(stream):
        step = cuts.randint(1, 7)
        got += parser.feed(bytes(stream[pos : pos + step]))
        pos += step
    assert [(f.command, f.payload) for f in got] == expected


@settings(max_examples=300)
@given(noise=st.binary(max_size=200))
def test_parser_never_raises_and_recovers_after_arbitrary_bytes(noise: bytes) -> None:
    parser = MspParser()
    parser.feed(noise)
    parser.abandon()  # a read timeout drops whatever partial frame the noise began
    good = encode_v2(m.MSP_ATTITUDE, b"\x01\x00\x02\x00\x03\x00", ">")
    assert parser.feed(good) == [MspFrame(2, ">", m.MSP_ATTITUDE, b"\x01\x00\x02\x00\x03\x00")]


def test_bad_checksum_is_counted_and_the_next_frame_survives() -> None:
    bad = bytearray(encode_v2(m.MSP_ATTITUDE, b"abcdef", ">"))
    bad[-1] ^= 0xFF
    parser = MspParser()
    frames = parser.feed(bytes(bad) + encode_v1(m.MSP_API_VERSION, b"\x00\x01\x2f", ">"))
    assert [f.command for f in frames] == [m.MSP_API_VERSION]
    assert parser.counters.bad_checksums == 1


def test_oversized_length_is_rejected_without_waiting_for_it() -> None:
    parser = MspParser(max_payload=64)
    huge = b"$X>\x00\x6c\x00\xff\x7f"  # claims 32767 bytes
    frames = parser.feed(huge + encode_v2(m.MSP_ALTITUDE, b"\x00" * 6, ">"))
    assert [f.command for f in frames] == [m.MSP_ALTITUDE]
    assert parser.counters.oversized == 1


def test_truncated_frame_is_counted_when_abandoned_and_parsing_resumes() -> None:
    parser = MspParser()
    whole = encode_v2(m.MSP_ATTITUDE, b"\x00" * 6, ">")
    assert parser.feed(whole[:7]) == []
    parser.abandon()
    assert parser.counters.truncated == 1
    assert len(parser.feed(whole)) == 1


def test_truncated_frame_followed_by_a_good_one_costs_at_most_the_truncated_frame() -> None:
    parser = MspParser()
    whole = encode_v2(m.MSP_ATTITUDE, b"\x00" * 6, ">")
    frames = parser.feed(whole[:5] + whole + whole)
    # The truncated head swallows bytes of the next frame; the parser resynchronises by the third.
    assert frames and all(f.command == m.MSP_ATTITUDE for f in frames)
    assert parser.counters.bad_checksums + parser.counters.garbage_bytes > 0


def test_error_replies_are_frames_and_are_counted() -> None:
    parser = MspParser()
    frames = parser.feed(encode_v1(99, b"", "!") + encode_v2(0x1234, b"", "!"))
    assert [f.is_error for f in frames] == [True, True]
    assert parser.counters.error_replies == 2


def test_payload_layouts_round_trip() -> None:
    assert m.Attitude.decode(m.Attitude(-1.5, 2.3, 271).encode()) == m.Attitude(-1.5, 2.3, 271.0)
    assert m.Altitude.decode(m.Altitude(1.23, -0.4).encode()) == m.Altitude(1.23, -0.4)
    assert m.Rangefinder.decode(m.Rangefinder(1.57).encode()).distance_m == 1.57
    assert m.Rangefinder.decode(m.Rangefinder(None).encode()).distance_m is None
    imu = m.RawImu((1, 2, 512), (-3, 4, 5), (0, 0, 0))
    assert m.RawImu.decode(imu.encode()) == imu
    assert m.Analog.decode(m.Analog(7.42, 120, 1.5).encode()) == m.Analog(7.42, 120, 1.5)
    assert m.decode_motors(m.encode_motors([1500, 1600, 1400, 1000])) == (1500, 1600, 1400, 1000, 0, 0, 0, 0)


def test_short_payload_is_a_clear_error() -> None:
    try:
        m.Attitude.decode(b"\x00\x01")
    except m.PayloadError as exc:
        assert "MSP_ATTITUDE" in str(exc)
    else:
        raise AssertionError("short payload accepted")
