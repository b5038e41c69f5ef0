"""End to end against a real ``feelium run --sim`` on a loopback port: real sockets, real clients."""

from __future__ import annotations

import asyncio
import json
import socket
import time

import aiohttp
import cv2
import numpy as np
import pytest

pytestmark = pytest.mark.slow


async def read_mjpeg_frames(resp: aiohttp.ClientResponse, n: int) -> list[tuple[int, bytes]]:
    """``n`` (seq, jpeg) parts from a multipart/x-mixed-replace stream."""
    frames = []
    while len(frames) < n:
        line = await resp.content.readline()
        if line != b"--feeliumframe\r\n":
            continue
        headers = {}
        while (line := await resp.content.readline()) != b"\r\n":
            key, _, value = line.decode().partition(":")
            headers[key.lower()] = value.strip()
        frames.append((int(headers["x-frame-seq"]), await resp.content.readexactly(int(headers["content-length"]))))
    return frames


def test_health_is_public_and_the_rest_needs_the_token(live):
    assert live.health()["services"]["http"]["healthy"] is True
    import urllib.error
    import urllib.request

    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(f"{live.api}/state", timeout=5)
    assert err.value.code == 401 and json.load(err.value)["error"] == "unauthorized"


def test_opencv_decodes_the_mjpeg_stream(live):
    cap = cv2.VideoCapture(f"{live.api}/video/front.mjpeg?token={live.token}", cv2.CAP_FFMPEG)
    try:
        assert cap.isOpened()
        frames = []
        for _ in range(5):
            ok, frame = cap.read()
            assert ok
            frames.append(frame)
    finally:
        cap.release()
    assert frames[0].ndim == 3 and frames[0].shape[2] == 3 and frames[0].shape[0] >= 24
    assert any(not np.array_equal(frames[0], f) for f in frames[1:])  # the video moves


async def test_a_stalled_client_neither_slows_another_nor_stays_connected(live):
    before = live.health()["services"]["http"].get("stalled_clients_dropped", 0)
    stalled = socket.socket()
    stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connect, so the window stays small
    stalled.connect(("127.0.0.1", live.port))
    stalled.sendall(f"GET /api/v1/video/front.mjpeg?token={live.token} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
    try:
        async with aiohttp.ClientSession() as session:
            async with session.get(f"{live.api}/video/front.mjpeg", headers=live.auth) as resp:
                frames = await asyncio.wait_for(read_mjpeg_frames(resp, 45), 30)
        seqs = [s for s, _ in frames]
        delivered = len(seqs) / (seqs[-1] - seqs[0] + 1)
        assert delivered >= 0.9, f"the reading client got {delivered:.0%} of the frames published"
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            if live.health()["services"]["http"].get("stalled_clients_dropped", 0) > before:
                break
            await asyncio.sleep(0.2)
        assert live.health()["services"]["http"].get("stalled_clients_dropped", 0) > before
    finally:
        stalled.close()


async def test_dead_man_stops_motion_when_not_refreshed(live):
    async with aiohttp.ClientSession(headers=live.auth) as session:
        async with session.post(f"{live.api}/motion", json={"command": "forward", "hold_ms": 300}) as resp:
            assert resp.status == 200 and (await resp.json())["active"] is True
        for _ in range(3):  # refreshed: still moving
            await asyncio.sleep(0.15)
            async with session.post(f"{live.api}/motion", json={"command": "forward", "hold_ms": 300}):
                pass
        async with session.get(f"{live.api}/motion") as resp:
            assert (await resp.json())["command"] == "forward"
        await asyncio.sleep(0.45)  # the headset froze
        async with session.get(f"{live.api}/motion") as resp:
            assert (await resp.json()) == {"command": "stop", "active": False, "remaining_ms": 0, "source": None}


async def _touch_from_longpoll(session: aiohttp.ClientSession, api: str, after: int) -> dict:
    while True:
        async with session.get(f"{api}/events", params={"after": after, "timeout": 1}) as resp:
            body = await resp.json()
        for item in body["events"]:
            if item["type"] == "touch" and item["event"]["phase"] == "down":
                return item
        after = body["last_seq"]


async def _touch_from_sse(session: aiohttp.ClientSession, api: str, after: int) -> dict:
    async with session.get(f"{api}/events/stream", headers={"Last-Event-ID": str(after)}) as resp:
        async for raw in resp.content:
            line = raw.decode()
            if line.startswith("data: "):
                item = json.loads(line[6:])
                if item["type"] == "touch" and item["event"]["phase"] == "down":
                    return item
    raise AssertionError("SSE stream ended")


async def _touch_from_ws(session: aiohttp.ClientSession, api: str, after: int, token: str) -> dict:
    async with session.ws_connect(f"{api.replace('http', 'ws', 1)}/events/ws?after={after}&token={token}") as ws:
        async for msg in ws:
            item = json.loads(msg.data)
            if item["type"] == "touch" and item["event"]["phase"] == "down":
                return item
    raise AssertionError("WebSocket closed")


async def test_a_simulated_touch_reaches_long_poll_sse_and_websocket(live):
    async with aiohttp.ClientSession(headers=live.auth) as session:
        async with session.get(f"{live.api}/sim") as resp:
            sim = await resp.json()
        assert sim["sim"] is True and sim["width"] > 0
        async with session.get(f"{live.api}/events", params={"timeout": 0}) as resp:
            after = (await resp.json())["last_seq"]
        waiters = [
            asyncio.create_task(_touch_from_longpoll(session, live.api, after)),
            asyncio.create_task(_touch_from_sse(session, live.api, after)),
            asyncio.create_task(_touch_from_ws(session, live.api, after, live.token)),
        ]
        await asyncio.sleep(0.3)
        x, y = sim["width"] / 2, sim["height"] / 2
        pressed_at = await _daemon_clock(session, live.api)
        async with session.post(f"{live.api}/sim/press", json={"x": x, "y": y}) as resp:
            assert resp.status == 202
        try:
            got = await asyncio.wait_for(asyncio.gather(*waiters), 20)
        finally:
            async with session.post(f"{live.api}/sim/release") as resp:
                assert resp.status == 202
            for task in waiters:
                task.cancel()
    assert got[0] == got[1] == got[2]  # one envelope, three transports
    event = got[0]["event"]
    assert abs(event["x"] - x) < 40 and abs(event["y"] - y) < 40, event
    assert pressed_at <= event["t"] <= pressed_at + 5.0  # on the daemon's clock, stamped after the press


async def _daemon_clock(session: aiohttp.ClientSession, api: str) -> float:
    async with session.get(f"{api}/clock") as resp:
        return (await resp.json())["t"]


async def test_every_camera_frame_is_stamped_on_the_daemon_clock(live):
    """``X-Feelium-Capture-T`` of the front, rear and projector frames is on the clock ``GET /clock`` gives, so a
    headset measures a frame's age with it (the simulated cameras once counted from their own start)."""
    async with aiohttp.ClientSession(headers=live.auth) as session:
        for camera in ("front", "rear", "projector"):
            before = await _daemon_clock(session, live.api)
            async with session.get(f"{live.api}/video/{camera}.jpg") as resp:
                assert resp.status == 200, camera
                captured = float(resp.headers["X-Feelium-Capture-T"])
            after = await _daemon_clock(session, live.api)
            assert before - 5.0 <= captured <= after, (camera, before, captured, after)
