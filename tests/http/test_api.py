"""Every endpoint through aiohttp's test client, with its error paths."""

from __future__ import annotations

import asyncio
from dataclasses import replace
import io
import json
import wave

import cv2
import numpy as np
import pytest

from feelium.events import SpeechIn, SpeechOut
from feelium.events import InteractionEvent, PresenceEvent, TouchEvent, WearerAction
from feelium.http.app import create_app
from tests.http.http_support import AUTH, TOKEN, FakeScene


def touch(i: int, t: float = 1.0) -> TouchEvent:
    return TouchEvent(i, "down", None, t, 320.0, 240.0, 0.5, 0.5, 0.4, 120, 0.9)


def jpeg_bytes(value: int = 128) -> bytes:
    ok, buf = cv2.imencode(".jpg", np.full((24, 32, 3), value, np.uint8))
    assert ok
    return buf.tobytes()


def wav_bytes(samples: np.ndarray, rate: int, channels: int = 1, width: int = 2) -> bytes:
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(channels)
        w.setsampwidth(width)
        w.setframerate(rate)
        w.writeframes(samples.tobytes())
    return buf.getvalue()


async def assert_error(resp, status: int, fragment: str) -> dict:  # type: ignore[no-untyped-def]
    assert resp.status == status, await resp.text()
    assert resp.content_type == "application/json"
    body = await resp.json()
    assert set(body) == {"error", "message"}
    assert fragment.lower() in body["message"].lower(), body
    return body


# --- auth, CORS, errors -------------------------------------------------------------------------------


async def test_health_without_the_token_says_only_alive_and_with_it_reports_the_supervisor(client, hub):
    hub.health = lambda: {"status": "degraded", "services": {"touch": {"healthy": False, "fps": float("nan")}}}
    for headers in ({}, {"Authorization": "Bearer wrong-token-0123456789"}):
        resp = await client.get("/api/v1/health", headers=headers)
        assert resp.status == 200 and await resp.json() == {"status": "alive"}  # nothing about who is near or wearing
    resp = await client.get("/api/v1/health", headers=AUTH)
    assert resp.status == 200
    body = await resp.json()
    assert body["status"] == "degraded"
    assert body["services"]["touch"]["fps"] is None  # NaN is not JSON


@pytest.mark.parametrize("path", ["/api/v1/state", "/api/v1/events", "/api/v1/motion", "/api/v1/video/front.jpg", "/api/v1/sim"])
async def test_every_api_endpoint_but_health_needs_the_token(client, path):
    await assert_error(await client.get(path), 401, "token")
    await assert_error(await client.get(path, headers={"Authorization": "Bearer wrong-token-xxxxxxxxxxxx"}), 401, "token")
    await assert_error(await client.get(path, headers={"Authorization": TOKEN}), 401, "token")  # no scheme
    resp = await client.get(path, headers=AUTH)
    assert resp.status != 401


async def test_token_in_query_is_accepted_for_clients_that_cannot_set_headers(client):
    assert (await client.get(f"/api/v1/state?token={TOKEN}")).status == 200


async def test_unauthorized_counts_are_reported(client):
    await client.get("/api/v1/state")
    assert client.link.counters["unauthorized"] == 1


async def test_unknown_path_and_wrong_method_are_json(client):
    await assert_error(await client.get("/api/v1/nope", headers=AUTH), 404, "no such endpoint")
    await assert_error(await client.delete("/api/v1/motion", headers=AUTH), 405, "not allowed")


async def test_foreign_origin_is_refused_and_own_origin_allowed(client):
    host = f"http://{client.server.host}:{client.server.port}"
    resp = await client.get("/api/v1/state", headers=AUTH | {"Origin": "http://evil.example"})
    await assert_error(resp, 403, "cors_origins")
    resp = await client.get("/api/v1/state", headers=AUTH | {"Origin": host})
    assert resp.status == 200
    assert resp.headers["Access-Control-Allow-Origin"] == host


async def test_preflight_for_a_configured_origin(aiohttp_client, hub, http_config):
    from dataclasses import replace

    from feelium.http.app import create_app

    app = create_app(replace(http_config, cors_origins="https://headset.local:8443, http://x"), hub, TOKEN)
    c = await aiohttp_client(app)
    resp = await c.options(
        "/api/v1/motion",
        headers={"Origin": "https://headset.local:8443", "Access-Control-Request-Method": "POST"},
    )
    assert resp.status == 204
    assert resp.headers["Access-Control-Allow-Origin"] == "https://headset.local:8443"
    assert "Authorization" in resp.headers["Access-Control-Allow-Headers"]
    assert "X-Feelium-Client" in resp.headers["Access-Control-Allow-Headers"]  # the client id of rate limits and the lease
    resp = await c.options("/api/v1/motion", headers={"Origin": "https://other", "Access-Control-Request-Method": "POST"})
    await assert_error(resp, 403, "cors_origins")


# --- motion -------------------------------------------------------------------------------------------


async def test_motion_is_a_dead_man_command(client, hub, clock):
    resp = await client.post("/api/v1/motion", json={"command": "forward", "hold_ms": 300}, headers=AUTH)
    assert resp.status == 200
    body = await resp.json()
    assert body["command"] == "forward" and body["active"] and body["remaining_ms"] == 300
    clock.now += 0.2
    assert hub.motion.active(clock.now).name == "forward"
    clock.now += 0.2
    assert hub.motion.active(clock.now) is None
    body = await (await client.get("/api/v1/motion", headers=AUTH)).json()
    assert body == {"command": "stop", "active": False, "remaining_ms": 0, "source": None}


async def test_motion_default_hold_and_stop(client, hub, clock):
    await client.post("/api/v1/motion", json={"command": "turn_left"}, headers=AUTH)
    assert hub.motion.active(clock.now + 0.49).name == "turn_left"
    assert hub.motion.active(clock.now + 0.51) is None
    await client.post("/api/v1/motion", json={"command": "up"}, headers=AUTH)
    await client.post("/api/v1/motion", json={"command": "stop"}, headers=AUTH)
    assert hub.motion.active(clock.now) is None


@pytest.mark.parametrize(
    "body, fragment",
    [
        ({"command": "sideways"}, "command must be one of"),
        ({}, "command must be one of"),
        ({"command": "up", "hold_ms": 0}, "hold_ms must be within"),
        ({"command": "up", "hold_ms": 5000}, "hold_ms must be within"),
        ({"command": "up", "hold_ms": "fast"}, "hold_ms must be a number"),
        ({"command": "up", "hold_ms": True}, "hold_ms must be a number"),
        ({"command": "up", "speed": 3}, "unknown field"),
        ([1, 2], "expected a json object"),
    ],
)
async def test_motion_rejects_bad_bodies(client, hub, body, fragment):
    await assert_error(await client.post("/api/v1/motion", json=body, headers=AUTH), 400, fragment)
    assert hub.motion.accepted == 0


async def test_motion_rejects_non_json(client):
    await assert_error(await client.post("/api/v1/motion", data=b"{nope", headers=AUTH | {"Content-Type": "application/json"}), 400, "not valid json")
    await assert_error(await client.post("/api/v1/motion", data=b"x=1", headers=AUTH | {"Content-Type": "application/x-www-form-urlencoded"}), 415, "application/json")
    await assert_error(await client.post("/api/v1/motion", headers=AUTH), 400, "json object body")


async def test_motion_body_limit_is_413(client):
    body = json.dumps({"command": "up", "pad": "x" * 20000})
    await assert_error(await client.post("/api/v1/motion", data=body, headers=AUTH | {"Content-Type": "application/json"}), 413, "limit")


async def test_motion_rate_limit_is_429_and_refills_with_time(client, clock, http_config):
    for _ in range(http_config.motion_burst):
        assert (await client.post("/api/v1/motion", json={"command": "up"}, headers=AUTH)).status == 200
    resp = await client.post("/api/v1/motion", json={"command": "up"}, headers=AUTH)
    await assert_error(resp, 429, "limited")
    assert int(resp.headers["Retry-After"]) >= 1
    clock.now += 1.0 / http_config.motion_rate_per_s
    assert (await client.post("/api/v1/motion", json={"command": "up"}, headers=AUTH)).status == 200


# --- events ------------------------------------------------------------------------------------------


async def test_long_poll_returns_published_events_in_order(client, hub):
    hub.bus.publish(touch(1))
    hub.bus.publish(PresenceEvent("approach", 1.0, 10.0, 12.0, 5.0, -2.0, 9, 3.5))
    hub.bus.publish(InteractionEvent("greeting_pat", "start", 1.1, 300.0, 200.0))
    await asyncio.sleep(0.01)
    body = await (await client.get("/api/v1/events?after=0", headers=AUTH)).json()
    assert [e["seq"] for e in body["events"]] == [1, 2, 3]
    assert [e["type"] for e in body["events"]] == ["touch", "presence", "interaction"]
    assert body["events"][0]["event"] == touch(1).to_json()
    assert body["reset"] is False and body["last_seq"] == 3
    body = await (await client.get("/api/v1/events?after=2", headers=AUTH)).json()
    assert [e["seq"] for e in body["events"]] == [3]


async def test_long_poll_waits_for_the_next_event(client, hub):
    async def later() -> None:
        await asyncio.sleep(0.05)
        hub.bus.publish(touch(7))

    task = asyncio.create_task(later())
    body = await (await client.get("/api/v1/events?after=0&timeout=5", headers=AUTH)).json()
    await task
    assert [e["event"]["id"] for e in body["events"]] == [7]


async def test_long_poll_times_out_empty(client):
    body = await (await client.get("/api/v1/events?after=0&timeout=0.05", headers=AUTH)).json()
    epoch = client.link.events.ring.epoch
    assert body == {"events": [], "last_seq": 0, "epoch": epoch, "resume": f"{epoch}:0", "reset": False}


async def test_client_too_far_behind_gets_reset_and_state(client, hub):
    hub.state.update("touch", contacts=1)
    for i in range(20):  # the ring holds 8 in these tests
        hub.bus.publish(touch(i))
    await asyncio.sleep(0.01)
    body = await (await client.get("/api/v1/events?after=2", headers=AUTH)).json()
    assert body["reset"] is True
    assert body["state"] == {"touch": {"contacts": 1}}
    assert body["events"] == [] and body["last_seq"] == 20  # the state replaces what was lost; nothing replayed
    body = await (await client.get("/api/v1/events?after=999", headers=AUTH)).json()
    assert body["reset"] is True  # a sequence this run never reached


async def test_after_a_restart_an_old_token_gets_a_snapshot_and_only_new_events(aiohttp_client, hub, http_config):
    """Two apps on one hub stand for a daemon and its restart: the new run numbers from 1 again."""
    first = await aiohttp_client(create_app(http_config, hub, TOKEN))
    for i in range(5):
        hub.bus.publish(touch(i))
    await asyncio.sleep(0.01)
    old = await (await first.get("/api/v1/events?after=0", headers=AUTH)).json()
    assert old["last_seq"] == 5
    await first.close()

    restarted = await aiohttp_client(create_app(http_config, hub, TOKEN))
    hub.state.update("touch", contacts=2)
    hub.bus.publish(touch(40))
    hub.bus.publish(touch(41))
    await asyncio.sleep(0.01)
    for old_token in (old["resume"], f"{old['epoch']}:1"):  # ahead of or behind the new numbers: both reset
        body = await (await restarted.get(f"/api/v1/events?after={old_token}", headers=AUTH)).json()
        assert body["epoch"] != old["epoch"] and body["reset"] is True and body["events"] == []
        assert body["state"] == {"touch": {"contacts": 2}}
    ws = await restarted.ws_connect(f"/api/v1/events/ws?after={old['resume']}", headers=AUTH)
    reset = await asyncio.wait_for(ws.receive_json(), 2)
    assert reset["type"] == "reset" and reset["epoch"] == body["epoch"] and reset["seq"] == 2
    hub.bus.publish(touch(42))
    new = await asyncio.wait_for(ws.receive_json(), 2)
    assert new["seq"] == 3 and new["event"]["id"] == 42  # never an old event, never a smaller number than the reset's
    await ws.close()
    resp = await restarted.get("/api/v1/events/stream", headers=AUTH | {"Last-Event-ID": old["resume"]})
    lines = []
    while not any(line.startswith("data: ") for line in lines):
        lines.append((await asyncio.wait_for(resp.content.readline(), 2)).decode())
    assert f"id: {body['epoch']}:3\n" in lines and "event: reset\n" in lines
    resp.close()


@pytest.mark.parametrize("query, fragment", [("after=-1", "after"), ("after=x", "integer"), ("after=e:1.5", "EPOCH:SEQ"), ("timeout=301", "timeout"), ("timeout=nan", "timeout")])
async def test_long_poll_rejects_bad_queries(client, query, fragment):
    await assert_error(await client.get(f"/api/v1/events?{query}", headers=AUTH), 400, fragment)


async def test_sse_delivers_events_and_resumes_after_last_event_id(client, hub):
    hub.bus.publish(touch(1))
    hub.bus.publish(touch(2))
    await asyncio.sleep(0.01)
    resp = await client.get("/api/v1/events/stream", headers=AUTH | {"Last-Event-ID": "1"})
    assert resp.status == 200 and resp.content_type == "text/event-stream"
    hub.bus.publish(touch(3))
    messages = []
    while len(messages) < 2:
        line = (await asyncio.wait_for(resp.content.readline(), 2)).decode()
        if line.startswith("data: "):
            messages.append(json.loads(line[6:]))
    assert [m["seq"] for m in messages] == [2, 3]
    assert messages[1]["event"]["id"] == 3
    epoch = client.link.events.ring.epoch
    resp.close()
    resp = await client.get("/api/v1/events/stream", headers=AUTH | {"Last-Event-ID": f"{epoch}:2"})  # the token SSE sent
    lines = []
    while not any(line.startswith("data: ") for line in lines):
        lines.append((await asyncio.wait_for(resp.content.readline(), 2)).decode())
    assert f"id: {epoch}:3\n" in lines
    resp.close()
    await assert_error(await client.get("/api/v1/events/stream", headers=AUTH | {"Last-Event-ID": "abc"}), 400, "Last-Event-ID")


async def test_websocket_delivers_the_same_envelopes(client, hub):
    ws = await client.ws_connect(f"/api/v1/events/ws?token={TOKEN}&after=0")
    hub.bus.publish(touch(5))
    hub.bus.publish(WearerAction("heart", 2.0))
    first = await asyncio.wait_for(ws.receive_json(), 2)
    second = await asyncio.wait_for(ws.receive_json(), 2)
    assert first == {"seq": 1, "epoch": client.link.events.ring.epoch, "type": "touch", "event": touch(5).to_json()}
    assert second["type"] == "wearer_action" and second["event"]["action"] == "heart"
    await ws.close()


async def test_websocket_endpoint_without_upgrade_is_400(client):
    await assert_error(await client.get("/api/v1/events/ws", headers=AUTH), 400, "websocket")


# --- video ------------------------------------------------------------------------------------------


async def test_jpeg_is_404_before_a_frame_then_the_newest_frame(client, hub):
    await assert_error(await client.get("/api/v1/video/front.jpg", headers=AUTH), 404, "no front frame")
    hub.front_video.publish(1.0, np.full((48, 64, 3), 30, np.uint8))
    hub.front_video.publish(2.0, np.full((48, 64, 3), 200, np.uint8))
    resp = await client.get("/api/v1/video/front.jpg", headers=AUTH)
    assert resp.status == 200 and resp.content_type == "image/jpeg"
    image = cv2.imdecode(np.frombuffer(await resp.read(), np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (48, 64, 3) and abs(float(image.mean()) - 200) < 3
    assert resp.headers["X-Frame-Seq"] == "2"


async def test_jpeg_is_encoded_once_per_frame(client, hub):
    hub.rear_video.publish(1.0, np.zeros((16, 16), np.uint8))
    for _ in range(3):
        assert (await client.get("/api/v1/video/rear.jpg", headers=AUTH)).status == 200
    assert client.link.videos["rear"].encoded == 1


async def test_a_jpeg_the_camera_encoded_is_forwarded_byte_for_byte_never_encoded_again(client, hub):
    from feelium.cameras.base import Jpeg

    data = cv2.imencode(".jpg", np.full((48, 64, 3), 120, np.uint8))[1].tobytes()  # as the VideoCore made it
    hub.front_video.publish(1.0, Jpeg(data, 64, 48))
    resp = await client.get("/api/v1/video/front.jpg", headers=AUTH)
    assert resp.status == 200 and resp.content_type == "image/jpeg" and await resp.read() == data
    stream = await client.get(f"/api/v1/video/front.mjpeg?token={TOKEN}")
    assert (await stream.content.readline()) == b"--feeliumframe\r\n"
    headers = {}
    while (line := await stream.content.readline()) != b"\r\n":
        key, _, val = line.decode().partition(":")
        headers[key] = val.strip()
    assert await stream.content.readexactly(int(headers["Content-Length"])) == data
    stream.close()
    feed = client.link.videos["front"]
    assert (feed.encoded, feed.forwarded, feed.bad_frames) == (0, 1, 0)


async def test_unknown_camera_and_bad_frame(client, hub):
    await assert_error(await client.get("/api/v1/video/back.jpg", headers=AUTH), 404, "no camera")
    hub.projector_video.publish(1.0, "not an image")
    await assert_error(await client.get("/api/v1/video/projector.jpg", headers=AUTH), 404, "no projector frame")
    assert client.link.videos["projector"].bad_frames == 1


async def test_mjpeg_stream_parts_decode(client, hub):
    hub.front_video.publish(1.0, np.full((32, 32, 3), 50, np.uint8))
    resp = await client.get(f"/api/v1/video/front.mjpeg?token={TOKEN}")
    assert resp.headers["Content-Type"] == "multipart/x-mixed-replace; boundary=feeliumframe"
    frames = []
    for value in (50, 150):
        assert (await resp.content.readline()) == b"--feeliumframe\r\n"
        headers = {}
        while (line := await resp.content.readline()) != b"\r\n":
            key, _, val = line.decode().partition(":")
            headers[key] = val.strip()
        data = await resp.content.readexactly(int(headers["Content-Length"]))
        assert (await resp.content.readexactly(2)) == b"\r\n"
        frames.append(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE))
        if value == 50:
            hub.front_video.publish(2.0, np.full((32, 32, 3), 150, np.uint8))
    assert [round(float(f.mean()), -1) for f in frames] == [50, 150]
    resp.close()


async def test_mjpeg_stream_limit_is_429(aiohttp_client, hub, http_config):
    from dataclasses import replace

    from feelium.http.app import create_app

    c = await aiohttp_client(create_app(replace(http_config, max_stream_clients=1), hub, TOKEN))
    hub.front_video.publish(1.0, np.zeros((8, 8), np.uint8))
    first = await c.get("/api/v1/video/front.mjpeg", headers=AUTH)
    assert first.status == 200
    await assert_error(await c.get("/api/v1/video/front.mjpeg", headers=AUTH), 429, "streams")
    first.close()


# --- face, actions, speech, sim, state ------------------------------------------------------------------


async def test_face_jpeg_is_published_for_the_projector(client, hub):
    data = jpeg_bytes()
    resp = await client.put("/api/v1/face", data=data, headers=AUTH | {"Content-Type": "image/jpeg"})
    assert resp.status == 200 and (await resp.json())["frames"] == 1
    assert hub.face.get().value == data


async def test_a_face_stays_until_cleared_with_delete(client, hub, clock):
    data = jpeg_bytes()
    await client.put("/api/v1/face", data=data, headers=AUTH | {"Content-Type": "image/jpeg"})
    clock.now += 600.0
    assert hub.face.get().value == data  # nothing on the link replaces it by itself
    resp = await client.delete("/api/v1/face", headers=AUTH)
    assert resp.status == 200 and await resp.json() == {"cleared": True}
    assert hub.face.get().value is None
    assert (await client.delete("/api/v1/face")).status == 401


async def test_face_avatar_loops_frames(client, hub):
    import aiohttp

    frames = [jpeg_bytes(v) for v in (10, 100, 200)]
    shown: list[int] = []  # every frame handed to the projector, in order (a reader of the slot may skip some)
    publish = hub.face.publish
    hub.face.publish = lambda t, value: (shown.append(frames.index(value)), publish(t, value))[1]
    form = aiohttp.FormData()
    for i, f in enumerate(frames):
        form.add_field("frame", f, filename=f"{i}.jpg", content_type="image/jpeg")
    resp = await client.put("/api/v1/face?fps=50", data=form, headers=AUTH)
    assert resp.status == 200, await resp.text()
    assert (await resp.json())["frames"] == 3
    for _ in range(500):
        if len(shown) >= 5:
            break
        await asyncio.sleep(0.01)
    assert shown[:5] == [0, 1, 2, 0, 1]


@pytest.mark.parametrize(
    "data, ctype, status, fragment",
    [
        (b"hello", "image/jpeg", 400, "not a jpeg"),
        (b"\xff\xd8\xff\xe0" + b"0" * 100, "image/jpeg", 400, "truncated"),
        (b"GIF89a", "image/gif", 415, "image/jpeg"),
        (b"\xff\xd8\xff" + b"0" * 3_000_000 + b"\xff\xd9", "image/jpeg", 413, "limit"),
    ],
)
async def test_face_rejects_bad_uploads(client, hub, data, ctype, status, fragment):
    await assert_error(await client.put("/api/v1/face", data=data, headers=AUTH | {"Content-Type": ctype}), status, fragment)
    assert hub.face.get() is None


@pytest.mark.parametrize("action", ["heart", "palm_raise", "palm_lower", "shimmer"])
async def test_wearer_actions_are_published(client, hub, clock, action):
    sub = hub.bus.subscribe([WearerAction])
    resp = await client.post(f"/api/v1/actions/{action}", headers=AUTH)
    assert resp.status == 202
    assert sub.get_nowait() == WearerAction(action, clock.now, {})


async def test_guess_carries_the_word(client, hub):
    sub = hub.bus.subscribe([WearerAction])
    resp = await client.post("/api/v1/actions/guess", json={"word": " heart "}, headers=AUTH)
    assert (await resp.json())["word"] == "heart"
    assert sub.get_nowait().detail == {"word": "heart"}
    await assert_error(await client.post("/api/v1/actions/guess", json={"word": ""}, headers=AUTH), 400, "word")
    await assert_error(await client.post("/api/v1/actions/guess", headers=AUTH), 400, "json object")
    await assert_error(await client.post("/api/v1/actions/heart", json={"x": 1}, headers=AUTH), 400, "unknown field")
    await assert_error(await client.post("/api/v1/actions/wave", headers=AUTH), 404, "no action")


async def test_speech_in_is_resampled_and_published(client, hub):
    sub = hub.bus.subscribe([SpeechIn])
    samples = (np.sin(np.arange(800) / 5) * 8000).astype("<i2")
    resp = await client.post("/api/v1/speech", data=wav_bytes(samples, 8000), headers=AUTH | {"Content-Type": "audio/wav"})
    assert resp.status == 202
    body = await resp.json()
    assert body == {"samples": 1600, "rate": 16000, "ms": 100.0}
    chunk = sub.get_nowait()
    assert chunk.rate == 16000 and len(chunk.pcm) == 3200


@pytest.mark.parametrize(
    "data, ctype, status, fragment",
    [
        (b"RIFFnope", "audio/wav", 400, "not a pcm wav"),
        (wav_bytes(np.zeros(10, np.uint8), 16000, width=1), "audio/wav", 400, "16-bit"),
        (b"x", "text/plain", 415, "audio/wav"),
        (wav_bytes(np.zeros(200_000, "<i2"), 16000), "audio/wav", 413, "limit"),
    ],
)
async def test_speech_in_rejects_bad_audio(client, data, ctype, status, fragment):
    await assert_error(await client.post("/api/v1/speech", data=data, headers=AUTH | {"Content-Type": ctype}), status, fragment)


async def test_speech_out_returns_new_chunks_as_wav(client, hub):
    resp = await client.get("/api/v1/speech?after=0&timeout=0.05", headers=AUTH)
    assert resp.status == 204 and resp.headers["X-Speech-Seq"] == "0"
    hub.bus.publish(SpeechOut(b"\x01\x00" * 160, 16000, 1.0))
    hub.bus.publish(SpeechOut(b"\x02\x00" * 160, 16000, 1.01))
    resp = await client.get("/api/v1/speech?after=0&timeout=1", headers=AUTH)
    assert resp.status == 200 and resp.headers["X-Speech-Seq"] == "2"
    with wave.open(io.BytesIO(await resp.read())) as w:
        assert w.getframerate() == 16000 and w.getnframes() == 320
    resp = await client.get("/api/v1/speech?after=1", headers=AUTH)
    with wave.open(io.BytesIO(await resp.read())) as w:
        assert w.readframes(1) == b"\x02\x00"


async def test_sim_endpoints_are_404_without_a_scene(client):
    assert await (await client.get("/api/v1/sim", headers=AUTH)).json() == {"sim": False}
    await assert_error(await client.post("/api/v1/sim/press", json={"x": 1, "y": 1}, headers=AUTH), 404, "sim mode")
    await assert_error(await client.post("/api/v1/sim/release", headers=AUTH), 404, "sim mode")


async def test_sim_press_and_release_reach_the_scene(client, hub, clock):
    scene = FakeScene()
    hub.rear_scene = scene
    assert (await (await client.get("/api/v1/sim", headers=AUTH)).json())["width"] == 640
    assert (await client.post("/api/v1/sim/press", json={"x": 100, "y": 50.5, "hover": True}, headers=AUTH)).status == 202
    assert (await client.post("/api/v1/sim/release", headers=AUTH)).status == 202
    assert scene.calls == [("press", 100.0, 50.5, clock.now, True), ("release", clock.now)]
    await assert_error(await client.post("/api/v1/sim/press", json={"x": 700, "y": 5}, headers=AUTH), 409, "outside the 640x480")
    await assert_error(await client.post("/api/v1/sim/press", json={"x": 5}, headers=AUTH), 400, "required")
    await assert_error(await client.post("/api/v1/sim/press", json={"x": 5, "y": 5, "hover": 1}, headers=AUTH), 400, "hover")
    await assert_error(await client.post("/api/v1/sim/press", json={"x": 0, "y": 5, "hover": True}, headers=AUTH), 409, "refused")


async def test_state_merges_services_motion_and_link(client, hub, clock):
    hub.state.update("flight", altitude_m=1.2, battery_v=np.float32(7.4))
    await client.post("/api/v1/motion", json={"command": "down"}, headers=AUTH)
    body = await (await client.get("/api/v1/state", headers=AUTH)).json()
    assert body["services"]["flight"]["altitude_m"] == 1.2
    assert abs(body["services"]["flight"]["battery_v"] - 7.4) < 1e-5
    assert body["motion_command"]["command"] == "down"
    assert body["headset_link"]["last_motion_age_s"] == 0.0


async def test_openapi_is_public_and_valid(client):
    from openapi_spec_validator import validate

    doc = await (await client.get("/api/v1/openapi.json")).json()
    validate(doc)
    assert doc["openapi"] == "3.1.0"
    routes = {r.resource.canonical for r in client.app.router.routes() if r.resource is not None}
    api = {r[len("/api/v1"):] for r in routes if r.startswith("/api/v1/") and r != "/api/v1/openapi.json"}
    assert api == set(doc["paths"]) - {"/actions/guess"}  # documented apart: its body differs from /actions/{action}
    operations = [op for item in doc["paths"].values() for op in item.values()]
    assert all("403" in op["responses"] for op in operations)  # a foreign Origin is refused everywhere


async def test_static_client_pages_are_served(client):
    for path in ("/", "/partner", "/static/app.js", "/static/style.css"):
        assert (await client.get(path)).status == 200, path


# --- one clock ------------------------------------------------------------------------------------


async def test_clock_maps_the_daemon_clock_to_wall_time(client, clock):
    client.link.wall_clock = lambda: 1_700_000_000.25
    resp = await client.get("/api/v1/clock", headers=AUTH)
    body = await resp.json()
    assert resp.status == 200
    assert body == {"t": 100.0, "wall": 1_700_000_000.25, "offset_s": 1_699_999_900.25, "uncertainty_s": 0.0}
    assert (await client.get("/api/v1/clock")).status == 401


async def test_frames_and_speech_carry_their_capture_time_on_the_daemon_clock(client, hub, clock):
    hub.front_video.publish(97.125, np.zeros((48, 64, 3), np.uint8))  # captured 2.875 s before "now" (100.0)
    resp = await client.get("/api/v1/video/front.jpg", headers=AUTH)
    assert resp.headers["X-Feelium-Capture-T"] == "97.125000"
    resp = await client.get("/api/v1/video/front.mjpeg", headers=AUTH)
    head = b""
    while not head.endswith(b"\r\n\r\n"):
        head += await asyncio.wait_for(resp.content.readline(), 2)
    assert b"X-Feelium-Capture-T: 97.125000\r\n" in head and b"X-Frame-Seq: 1\r\n" in head
    resp.close()
    hub.bus.publish(SpeechOut(b"\0\0" * 160, 16000, 99.5))
    await asyncio.sleep(0.02)
    resp = await client.get("/api/v1/speech?after=0", headers=AUTH)
    assert resp.status == 200 and resp.headers["X-Feelium-Capture-T"] == "99.500000"


# --- Host and Origin: DNS rebinding -----------------------------------------------------------------


@pytest.mark.parametrize("host", ["evil.example", "evil.example:8080", "127.0.0.1.nip.io", "10.9.9.9", ""])
async def test_a_host_that_is_not_the_blimps_is_refused_before_the_token_is_looked_at(client, host):
    """A rebinding page sends its own name as Host (and an Origin that matches it); both are refused."""
    for path in ("/api/v1/state", "/api/v1/health", "/"):
        resp = await client.get(path, headers=AUTH | {"Host": host, "Origin": f"http://{host}"})
        body = await assert_error(resp, 403, "not one of this blimp's names")
        assert body["error"] == "host_not_allowed"
    assert client.link.counters["host_not_allowed"] == 3


async def test_a_request_without_a_host_header_is_told_so(client):
    reader, writer = await asyncio.open_connection(client.server.host, client.server.port)
    writer.write(b"GET /api/v1/health HTTP/1.0\r\n\r\n")
    await writer.drain()
    answer = await asyncio.wait_for(reader.read(), 5)
    writer.close()
    assert answer.startswith(b"HTTP/1.0 403") and b"no Host header" in answer and b"None" not in answer


@pytest.mark.parametrize("host", ["localhost:8080", "LOCALHOST", "blimp.local", "blimp", "127.0.0.1:1234"])
async def test_the_blimps_own_names_and_the_address_the_connection_arrived_on_are_served(aiohttp_client, hub, http_config, monkeypatch, host):
    monkeypatch.setattr("feelium.http.app.socket.gethostname", lambda: "blimp")
    client = await aiohttp_client(create_app(http_config, hub, TOKEN))
    resp = await client.get("/api/v1/state", headers=AUTH | {"Host": host})
    assert resp.status == 200
    origin = f"http://{host.lower()}"  # the blimp's own page, loaded by that name
    assert (await client.get("/api/v1/state", headers=AUTH | {"Host": host, "Origin": origin})).status == 200


async def test_configured_hosts_replace_the_defaults(aiohttp_client, hub, http_config):
    client = await aiohttp_client(create_app(replace(http_config, allowed_hosts="feelium.example., other"), hub, TOKEN))
    assert (await client.get("/api/v1/state", headers=AUTH | {"Host": "feelium.example:443"})).status == 200
    assert (await client.get("/api/v1/state", headers=AUTH | {"Host": "localhost"})).status == 403


@pytest.mark.parametrize(
    "raw, ctype, ignored",
    [
        ('{"command": "stop", "x": 1}', "application/json", ["x"]),
        ('{"command": "stop", "hold_ms": 1e400, "take_over": "yes"}', "application/json", ["hold_ms", "take_over"]),
        ('{"command": "stop"}', "text/plain", None),
        ('{"command": "stop"}', "application/x-www-form-urlencoded", None),
    ],
    ids=["extra-field", "invalid-fields", "text-plain", "form-type"],
)
async def test_a_stop_wins_over_whatever_else_its_request_holds(client, hub, raw, ctype, ignored):
    """A stop refused for a formality would leave the blimp moving: it is applied, and what it ignored named."""
    assert (await client.post("/api/v1/motion", json={"command": "forward"}, headers=AUTH)).status == 200
    resp = await client.post("/api/v1/motion", data=raw.encode(), headers=AUTH | {"Content-Type": ctype})
    body = await resp.json()
    assert resp.status == 200 and body["accepted"] == "stop" and body["active"] is False
    assert body.get("ignored") == ignored
    assert hub.motion.active(hub.clock()) is None


async def test_anything_but_a_stop_keeps_the_strict_rules(client, hub):
    resp = await client.post("/api/v1/motion", data=b'{"command": "forward"}', headers=AUTH | {"Content-Type": "text/plain"})
    assert resp.status == 415
    resp = await client.post("/api/v1/motion", json={"command": "forward", "x": 1}, headers=AUTH)
    assert resp.status == 400 and hub.motion.active(hub.clock()) is None


@pytest.mark.parametrize(
    "raw",
    [b'\xef\xbb\xbf{"command": "stop"}', b'{"command": "stop", "hold_ms": NaN}', b'{"command": "stop", "x": "\xff\xfe"}',
     b'{"command": "stop"} trailing', b'{"command": "stop", "x": ' + b"[" * 13 + b"]" * 13 + b"}",
     b'{"command": "stop", "hold_ms": 1' + b"0" * 5000 + b"}"],
    ids=["bom", "nan", "bad-utf8-elsewhere", "trailing-data", "nested-13", "5000-digit-int"],
)
async def test_a_malformed_stop_still_stops(client, hub, raw):
    assert (await client.post("/api/v1/motion", json={"command": "forward"}, headers=AUTH)).status == 200
    resp = await client.post("/api/v1/motion", data=raw, headers=AUTH | {"Content-Type": "application/json"})
    assert resp.status == 200 and (await resp.json())["accepted"] == "stop"
    assert hub.motion.active(hub.clock()) is None
