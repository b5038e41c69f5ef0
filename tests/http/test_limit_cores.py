"""The pure cores behind issue 14's limits: per-client buckets, the motion lease, stream slots, JSON depth, JPEG sizes."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.http.clients import client_key
from feelium.http.lease import ControlLease
from feelium.http.params import json_depth
from feelium.http.ratelimit import ClientBuckets
from feelium.http.slots import SlotsFull, StreamSlots
from feelium.jpeginfo import JpegHeaderError, jpeg_size, reduction_for
from feelium.lab.http.abuse import declare_size


def test_one_clients_flood_leaves_anothers_bucket_full() -> None:
    limits = ClientBuckets(rate=10.0, burst=3)
    assert [limits.take("a", 0.0) for _ in range(5)] == [True, True, True, False, False]
    assert [limits.take("b", 0.0) for _ in range(3)] == [True, True, True]
    assert limits.rejected == 2
    assert limits.retry_after("a", 0.0) == pytest.approx(0.1)
    assert limits.retry_after("never-seen", 0.0) == 0.0
    assert limits.take("a", 0.1)  # refilled at its own rate


def test_buckets_are_bounded_and_forget_the_least_recently_seen() -> None:
    limits = ClientBuckets(rate=1.0, burst=1, max_clients=2)
    assert limits.take("a", 0.0) and limits.take("b", 0.0)
    assert not limits.take("a", 0.0)  # a is now the most recent
    assert limits.take("c", 0.0)  # evicts b, not a
    assert len(limits) == 2
    assert not limits.take("a", 0.0)
    with pytest.raises(ValueError):
        ClientBuckets(rate=0.0, burst=1)


def test_the_lease_is_exclusive_renewed_by_motion_and_lapses_when_quiet() -> None:
    lease = ControlLease(lease_s=5.0)
    assert lease.holder(0.0) is None
    assert lease.claim("a", 0.0) is None
    refused = lease.claim("b", 1.0)
    assert refused is not None and refused.client == "a" and refused.expires_at == 5.0
    assert lease.claim("a", 4.0) is None  # renewed
    assert lease.claim("b", 8.9) is not None
    assert lease.claim("b", 9.0) is None  # a went quiet for 5 s
    assert lease.holder(9.0).client == "b"
    assert lease.refused == 2 and lease.takeovers == 0


def test_take_over_and_a_stop_move_the_lease() -> None:
    lease = ControlLease(lease_s=5.0)
    lease.claim("a", 0.0)
    assert lease.claim("b", 1.0, take_over=True) is None
    assert lease.holder(1.0).client == "b" and lease.takeovers == 1
    lease.stopped_by("c", 2.0)
    assert lease.holder(2.0).client == "c"
    assert lease.claim("b", 3.0).client == "c"  # the stop sticks: b must take over again
    with pytest.raises(ValueError):
        ControlLease(0.0)


def test_stream_slots_per_client_and_in_total() -> None:
    slots = StreamSlots(total=3, per_client=2)
    slots.acquire("a")
    slots.acquire("a")
    with pytest.raises(SlotsFull, match="this client already has 2"):
        slots.acquire("a")
    slots.acquire("b")
    with pytest.raises(SlotsFull, match="all 3"):
        slots.acquire("c")
    slots.release("a")
    slots.acquire("c")
    assert slots.in_use == 3 and slots.held_by("a") == 1 and slots.refused == 2
    with pytest.raises(ValueError):
        slots.release("nobody")


@given(ids=st.lists(st.integers(0, 10_000), min_size=1, max_size=200), per_address=st.integers(1, 6))
def test_new_client_ids_from_one_address_get_no_more_than_the_address_allows(ids: list[int], per_address: int) -> None:
    """Ids are free to pick: however many a device invents, at one instant its requests are capped by its
    address's bucket (per-address times one client's burst), and another address keeps its own allowance."""
    limits = ClientBuckets(rate=4.0, burst=3, clients_per_address=per_address)
    accepted = sum(limits.take(client_key("10.0.0.9", f"id-{i}"), 0.0) for i in ids)
    each_id = sum(min(ids.count(i), 3) for i in set(ids))  # what per-client buckets alone would accept
    assert accepted == min(each_id, 3 * per_address)
    assert limits.take(client_key("10.0.0.2", "other"), 0.0)


def test_stream_slots_per_address_whatever_the_ids() -> None:
    slots = StreamSlots(total=16, per_client=4, per_address=8)
    for i in range(8):
        slots.acquire(f"10.0.0.9/reader-{i}")
    with pytest.raises(SlotsFull, match="this address already has 8"):
        slots.acquire("10.0.0.9/reader-new")
    slots.acquire("10.0.0.2/headset")  # another device still finds a slot
    slots.release("10.0.0.9/reader-0")
    slots.acquire("10.0.0.9/reader-new")
    assert slots.in_use == 9 and slots.refused == 1


def test_client_key() -> None:
    assert client_key("10.0.0.2", None) == "10.0.0.2"
    assert client_key("10.0.0.2", "vision-1") == "10.0.0.2/vision-1"
    assert client_key(None, None) == "local"


@pytest.mark.parametrize(
    "text, depth",
    [
        ("{}", 1),
        ('{"a": [1, {"b": []}]}', 4),
        ('{"a": "[[[[{{{{"}', 1),
        ('{"a": "\\"[[["}', 1),
        ("[" * 5000 + "]" * 5000, 5000),
        ("3", 0),
    ],
)
def test_json_depth_ignores_brackets_in_strings(text: str, depth: int) -> None:
    assert json_depth(text) == depth


def _jpeg(h: int, w: int, **flags: int) -> bytes:
    params = [v for kv in flags.items() for v in (getattr(cv2, kv[0]), kv[1])]
    ok, buf = cv2.imencode(".jpg", np.zeros((h, w, 3), np.uint8), params)
    assert ok
    return buf.tobytes()


def test_jpeg_size_from_the_header_of_baseline_and_progressive_files() -> None:
    assert jpeg_size(_jpeg(48, 64)) == (64, 48)
    assert jpeg_size(_jpeg(30, 20, IMWRITE_JPEG_PROGRESSIVE=1)) == (20, 30)
    assert jpeg_size(declare_size(_jpeg(8, 8), 8000, 8000)) == (8000, 8000)
    with pytest.raises(JpegHeaderError, match="not a JPEG"):
        jpeg_size(b"\x89PNG\r\n")
    with pytest.raises(JpegHeaderError, match="no frame header"):
        jpeg_size(b"\xff\xd8\xff\xd9")
    with pytest.raises(JpegHeaderError, match="no marker"):
        jpeg_size(b"\xff\xd8\x00\x00\x00\x00")


@pytest.mark.parametrize(
    "size, need, factor",
    [((4096, 4096), (512, 384), 8), ((2048, 1536), (512, 384), 4), ((1000, 800), (512, 384), 1),
     ((1100, 800), (512, 384), 2), ((100, 100), (512, 384), 1)],
)  # fmt: skip
def test_reduction_keeps_at_least_the_needed_size(size: tuple[int, int], need: tuple[int, int], factor: int) -> None:
    assert reduction_for(*size, *need) == factor
