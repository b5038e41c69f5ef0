"""GET /speech/stream: frames on the one clock, auth like the other streams, bounded slots and backlog, speech in."""

from __future__ import annotations

import asyncio
import base64
import json
import os
import socket
from dataclasses import replace

import aiohttp
import numpy as np
import pytest

from feelium.events import SpeechIn, SpeechOut
from feelium.http.app import create_app, link_of
from feelium.http.speech_stream import HEADER_BYTES, BacklogGate, SpeechFrame, decode_frame, encode_frame, incoming_pcm

from tests.http.http_support import AUTH, TOKEN

PATH = "/api/v1/speech/stream"


async def until(condition, timeout: float = 3.0) -> bool:  # type: ignore[no-untyped-def]
    """Wait (bounded) for ``condition()`` to hold: the server side of a close runs on its own schedule."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not condition() and loop.time() < deadline:
        await asyncio.sleep(0.01)
    return bool(condition())


def chunk(i: int, t: float, samples: int = 640) -> SpeechOut:
    return SpeechOut(np.full(samples, i, dtype="<i2").tobytes(), 16000, t)


# --- pure cores -------------------------------------------------------------------------------------


def test_a_frame_round_trips_and_its_header_is_32_bytes() -> None:
    frame = SpeechFrame(2**40 + 3, 16000, 1234.567891, 7, b"\x01\x00\xff\x7f")
    data = encode_frame(frame)
    assert len(data) == HEADER_BYTES + 4 == 36
    assert decode_frame(data) == frame
    assert frame.header_json()["samples"] == 2
    with pytest.raises(ValueError):
        decode_frame(data[:20])
    with pytest.raises(ValueError):
        decode_frame(data[:-1])  # not whole samples


def test_the_gate_drops_while_behind_and_closes_only_without_progress() -> None:
    gate = BacklogGate(max_backlog_bytes=1000, stall_s=1.0)
    assert gate.decide(0, 0.0) == "send"
    assert gate.decide(5000, 0.1) == "drop"  # behind: drop, keep the slot
    assert gate.decide(4000, 0.9) == "drop"  # shrinking: progress
    assert gate.decide(4000, 1.5) == "drop"
    assert gate.decide(4000, 2.0) == "close"  # nothing accepted for more than 1 s
    assert BacklogGate(1000, 1.0).decide(None, 5.0) == "send"  # unknown backlog: only the write timeout guards


def test_incoming_pcm_is_resampled_and_must_be_whole_samples() -> None:
    pcm = np.arange(800, dtype="<i2").tobytes()  # 100 ms at 8 kHz
    assert len(incoming_pcm(pcm, 8000, 16000)) == 2 * 1600
    assert incoming_pcm(pcm, 16000, 16000) == pcm
    for bad in (b"", b"\x01"):
        with pytest.raises(ValueError):
            incoming_pcm(bad, 16000, 16000)


# --- the route ----------------------------------------------------------------------------------------


async def test_frames_carry_seq_capture_time_and_samples(client, hub, clock) -> None:
    async with client.ws_connect(PATH, headers=AUTH) as ws:
        hello = await ws.receive_json(timeout=2)
        assert hello["type"] == "hello" and hello["rate"] == 16000 and hello["header_bytes"] == HEADER_BYTES
        for i in range(3):
            hub.bus.publish(chunk(i + 1, 100.0 + 0.04 * i))
        frames = [decode_frame((await ws.receive(timeout=2)).data) for _ in range(3)]
    assert [f.seq for f in frames] == [1, 2, 3]
    assert [f.capture_t for f in frames] == pytest.approx([100.0, 100.04, 100.08])  # the daemon clock, as published
    assert all(f.dropped == 0 and f.rate == 16000 and f.pcm == chunk(f.seq, 0).pcm for f in frames)


async def test_resume_after_a_seq_gets_the_held_chunks_after_it(client, hub) -> None:
    for i in range(4):
        hub.bus.publish(chunk(i + 1, 100.0))
    assert await until(lambda: client.link.speech.last_seq == 4)
    async with client.ws_connect(PATH + "?after=2", headers=AUTH) as ws:
        assert (await ws.receive_json(timeout=2))["after"] == 2
        assert [decode_frame((await ws.receive(timeout=2)).data).seq for _ in range(2)] == [3, 4]


async def test_auth_is_the_header_the_session_cookie_or_the_query_like_the_event_socket(client) -> None:
    with pytest.raises(aiohttp.WSServerHandshakeError) as err:
        await client.ws_connect(PATH)
    assert err.value.status == 401
    resp = await client.post("/api/v1/session", headers=AUTH)  # the browser's way: an HttpOnly cookie
    assert resp.status == 204
    async with client.ws_connect(PATH) as ws:
        assert (await ws.receive_json(timeout=2))["type"] == "hello"
    resp = await client.get(PATH, headers=AUTH)  # not an upgrade: a 4xx JSON body
    assert resp.status == 400 and (await resp.json())["error"] == "bad_request"
    for bad in ("after=-1", "rate=1", "rate=x"):
        resp = await client.get(f"{PATH}?{bad}", headers=AUTH)
        assert resp.status == 400, bad


async def test_slots_per_client_and_in_total(aiohttp_client, hub, http_config) -> None:
    app = create_app(replace(http_config, max_speech_streams=3, max_speech_streams_per_client=2), hub, TOKEN)
    c = await aiohttp_client(app)
    a = [await c.ws_connect(PATH, headers=AUTH | {"X-Feelium-Client": "a"}) for _ in range(2)]
    resp = await c.get(PATH, headers=AUTH | {"X-Feelium-Client": "a", "Connection": "Upgrade", "Upgrade": "websocket",
                                              "Sec-WebSocket-Version": "13", "Sec-WebSocket-Key": base64.b64encode(os.urandom(16)).decode()})
    assert resp.status == 429 and "speech streams" in (await resp.json())["message"]
    b = await c.ws_connect(PATH, headers=AUTH | {"X-Feelium-Client": "b"})
    with pytest.raises(aiohttp.WSServerHandshakeError) as err:
        await c.ws_connect(PATH, headers=AUTH | {"X-Feelium-Client": "c"})
    assert err.value.status == 429
    await a[0].close()
    assert await until(lambda: link_of(app).speech_streams.held_by("127.0.0.1/a") == 1)
    d = await c.ws_connect(PATH, headers=AUTH | {"X-Feelium-Client": "c"})  # a closed stream frees its slot
    for ws in (*a[1:], b, d):
        await ws.close()
    assert await until(lambda: link_of(app).speech_streams.in_use == 0)


async def test_a_reader_that_stops_reading_loses_frames_then_its_slot(client, hub) -> None:
    """A raw socket with a tiny receive buffer does the handshake and never reads again."""
    link = client.link
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 2048)
    sock.connect(("127.0.0.1", client.port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        f"GET {PATH} HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {TOKEN}\r\nUpgrade: websocket\r\n"
        f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    try:
        await asyncio.sleep(0.05)
        for i in range(60):  # 60 chunks of 1 s each (32 kB): far more than a 200 ms backlog
            hub.bus.publish(chunk(i + 1, 100.0, samples=16000))
            await asyncio.sleep(0.01)
            if link.counters.get("stalled_clients_dropped", 0):
                break
        assert link.counters.get("speech_frames_dropped", 0) > 0
        for _ in range(100):
            if link.counters.get("stalled_clients_dropped", 0):
                break
            hub.bus.publish(chunk(99, 100.0, samples=16000))
            await asyncio.sleep(0.02)
        assert link.counters.get("stalled_clients_dropped", 0) == 1
        assert link.counters.get("speech_frames_sent", 0) <= 3  # never more than the backlog allows in flight
        assert await until(lambda: link.speech_streams.in_use == 0)
    finally:
        sock.close()


async def test_wearer_speech_in_is_published_resampled_and_rate_limited(aiohttp_client, hub, clock, http_config) -> None:
    app = create_app(replace(http_config, speech_rate_per_s=1.0, speech_burst=2), hub, TOKEN)
    c = await aiohttp_client(app)
    sub = hub.bus.subscribe([SpeechIn], maxsize=16)
    async with c.ws_connect(PATH + "?rate=8000", headers=AUTH) as ws:
        assert (await ws.receive_json(timeout=2))["in_rate"] == 8000
        await ws.send_bytes(np.ones(800, dtype="<i2").tobytes())  # 100 ms at 8 kHz
        got = await asyncio.wait_for(sub.get(), 2)
        assert got.rate == 16000 and len(got.pcm) == 2 * 1600
        await ws.send_bytes(b"\x01")  # half a sample
        notice = await ws.receive_json(timeout=2)
        assert notice["type"] == "notice" and notice["error"] == "bad_request"
        clock.now += 1.01  # notices are at most one a second (the bucket refills one token meanwhile)
        for _ in range(3):
            await ws.send_bytes(np.ones(160, dtype="<i2").tobytes())
        notice = await ws.receive_json(timeout=2)
        assert notice["error"] == "too_many_requests"
        await ws.send_bytes(b"\0" * (http_config.max_speech_bytes + 2))  # the POST's size limit: the socket closes
        msg = await ws.receive(timeout=2)
        assert msg.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING)
    assert link_of(app).speech_limit.rejected >= 1
    sub.close()


async def test_the_long_poll_still_works_beside_the_stream(client, hub) -> None:
    async with client.ws_connect(PATH, headers=AUTH) as ws:
        await ws.receive_json(timeout=2)
        hub.bus.publish(chunk(1, 100.0))
        frame = decode_frame((await ws.receive(timeout=2)).data)
    resp = await client.get("/api/v1/speech?after=0&timeout=0", headers=AUTH)
    assert resp.status == 200 and resp.headers["X-Speech-Seq"] == str(frame.seq)
    assert float(resp.headers["X-Feelium-Capture-T"]) == pytest.approx(frame.capture_t)
