"""The pure parts of the headset link: the event ring, the rate limit, the token, JPEG checks."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.events import TouchEvent
from feelium.http.auth import TokenError, load_or_create_token, presented_token, token_matches
from feelium.http.face import ImageTooLarge, JpegError, check_jpeg
from feelium.http.jpeg import FrameError, encode_jpeg
from feelium.http.ratelimit import TokenBucket
from feelium.http.ring import EventRing, envelope, parse_resume, resume_token


def touch(i: int) -> TouchEvent:
    return TouchEvent(i, "move", "hold", 0.5, 1.0, 2.0, 0.1, 0.2, 0.3, 4, 0.5)


@given(capacity=st.integers(1, 20), n=st.integers(0, 60), after=st.integers(0, 80))
def test_ring_returns_exactly_the_missing_events_or_resets(capacity: int, n: int, after: int) -> None:
    ring = EventRing(capacity, "e1")
    for i in range(n):
        ring.append(touch(i))
    got = ring.after(after)
    assert got.last_seq == n
    if after > n or after < n - capacity:
        assert got.reset and got.events == []  # a reset brings the state, never old events out of order
    else:
        assert not got.reset
        assert [e["seq"] for e in got.events] == list(range(after + 1, n + 1))
        assert got == ring.after(after, "e1")


@given(n=st.integers(0, 30), after=st.integers(0, 30))
def test_a_token_of_an_earlier_run_always_resets_and_numbers_never_go_back(n: int, after: int) -> None:
    """A restarted daemon numbers from 1 again: whatever the old token's number, the client gets a reset
    (the state) and then only events numbered above the reset's, never old events replayed."""
    ring = EventRing(8, "new-run")
    for i in range(n):
        ring.append(touch(i))
    got = ring.after(after, "old-run")
    assert got.reset and got.events == [] and got.last_seq == n
    ring.append(touch(99))
    assert [e["seq"] for e in ring.after(got.last_seq).events] == [n + 1]


def test_resume_tokens_round_trip_and_bad_ones_are_refused() -> None:
    assert parse_resume(resume_token("ab12cd34", 17), 2**53) == ("ab12cd34", 17)
    assert parse_resume("17", 2**53) == (None, 17)
    for bad in (":5", "x:", "x:-1", "5.0", "x:1e3", "x:" + "9" * 30, "١٢"):
        with pytest.raises(ValueError):
            parse_resume(bad, 2**53)


def test_envelope_is_the_one_wire_form() -> None:
    assert envelope(4, touch(1), "e") == {"seq": 4, "epoch": "e", "type": "touch", "event": touch(1).to_json()}


@given(rate=st.floats(0.5, 100), burst=st.integers(1, 30), gaps=st.lists(st.floats(0, 0.5), min_size=1, max_size=80))
def test_bucket_never_admits_more_than_burst_plus_rate_times_elapsed(rate: float, burst: int, gaps: list[float]) -> None:
    now = 10.0
    bucket = TokenBucket(rate, burst, now)
    admitted = 0
    for gap in gaps:
        now += gap
        admitted += bucket.take(now)
    assert admitted <= burst + rate * (now - 10.0) + 1e-9
    assert admitted + bucket.rejected == len(gaps)


def test_bucket_refills_and_ignores_a_clock_stepping_back() -> None:
    bucket = TokenBucket(2.0, 1, 0.0)
    assert bucket.take(0.0) and not bucket.take(0.1)
    assert bucket.retry_after(0.1) == pytest.approx(0.4)
    assert not bucket.take(-5.0)
    assert bucket.take(0.5)


def test_token_file_is_created_0600_and_reused(tmp_path) -> None:
    path = tmp_path / "sub" / "token"
    token = load_or_create_token("", str(path))
    assert len(token) >= 32
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    assert load_or_create_token("", str(path)) == token
    assert load_or_create_token("configured-token-xxxxxxxx", str(path)) == "configured-token-xxxxxxxx"


def test_token_file_permissions_are_tightened_and_short_tokens_refused(tmp_path) -> None:
    path = tmp_path / "token"
    path.write_text("a-long-enough-token-value\n")
    path.chmod(0o644)
    assert load_or_create_token("", str(path)) == "a-long-enough-token-value"
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    path.write_text("short")
    with pytest.raises(TokenError, match="shorter than 16"):
        load_or_create_token("", str(path))


def test_presented_token_and_comparison() -> None:
    assert presented_token({"Authorization": "Bearer abc"}, {"token": "q"}) == "abc"
    assert presented_token({"Authorization": "bearer  abc "}, {}) == "abc"
    assert presented_token({"Authorization": "Basic abc"}, {"token": "q"}) == "q"
    assert presented_token({}, {}) is None
    assert token_matches("secret", "secret")
    assert not token_matches("secreT", "secret") and not token_matches(None, "secret")
    assert not token_matches("s\udcff", "secret")  # undecodable input never raises


def test_jpeg_structure_check() -> None:
    good = encode_jpeg(np.zeros((8, 8), np.uint8), 80)
    assert check_jpeg(good, 64) == (8, 8)
    with pytest.raises(JpegError, match="not a JPEG"):
        check_jpeg(b"\x89PNG....", 64)
    with pytest.raises(JpegError, match="truncated"):
        check_jpeg(good[:-10], 64)
    with pytest.raises(ImageTooLarge, match="8x8 = 64 pixels; at most 63"):
        check_jpeg(good, 63)


def test_encode_jpeg_accepts_float_frames_and_names_bad_ones() -> None:
    data = encode_jpeg(np.full((4, 4, 3), 300.0), 90)
    assert data.startswith(b"\xff\xd8")
    with pytest.raises(FrameError, match="channels"):
        encode_jpeg(np.zeros((4, 4, 2), np.uint8), 90)
    with pytest.raises(FrameError, match="image array"):
        encode_jpeg([[1]], 90)
