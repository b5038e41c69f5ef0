"""Issue 14, points 1 and 2 through aiohttp's test client: stop always wins, and every input is bounded."""

from __future__ import annotations

import asyncio
import json
import socket
from dataclasses import replace

import cv2
import numpy as np
import pytest

from feelium.http.app import create_app, link_of
from tests.http.http_support import AUTH, TOKEN, FakeScene
from feelium.lab.http.abuse import declare_size

MOTION = "/api/v1/motion"


def as_client(name: str) -> dict[str, str]:
    return AUTH | {"X-Feelium-Client": name}


A, B = as_client("A"), as_client("B")


async def error_of(resp, status: int) -> dict:  # type: ignore[no-untyped-def]
    text = await resp.text()
    assert resp.status == status, text
    assert resp.content_type == "application/json", text
    body = json.loads(text)
    assert isinstance(body["error"], str) and isinstance(body["message"], str)
    return body


@pytest.fixture
def commands(hub):  # type: ignore[no-untyped-def]
    """Every command that reached the dead-man slot the flight loop reads, as (name, source)."""
    seen: list[tuple[str, str]] = []
    command = hub.motion.command

    def spy(name, now, hold_s=0.5, source="headset"):  # type: ignore[no-untyped-def]
        seen.append((name, source))
        return command(name, now, hold_s, source)

    hub.motion.command = spy
    return seen


# --- point 1: stop always wins ------------------------------------------------------------------------------


async def test_after_a_flood_stop_from_the_flooder_and_from_another_client_is_applied(client, hub, clock, commands, http_config):
    statuses = [(await client.post(MOTION, json={"command": "forward"}, headers=A)).status for _ in range(http_config.motion_burst + 20)]
    assert statuses.count(200) == http_config.motion_burst and statuses.count(429) == 20
    assert hub.motion.active(clock.now).name == "forward"
    resp = await client.post(MOTION, json={"command": "stop"}, headers=A)
    assert resp.status == 200 and (await resp.json())["accepted"] == "stop"
    assert hub.motion.active(clock.now) is None  # the flight loop's next read holds position
    clock.now += 0.01  # A's bucket is still empty (refills one every 40 ms): its stop needs none
    assert (await client.post(MOTION, json={"command": "forward"}, headers=A)).status == 429
    resp = await client.post(MOTION, json={"command": "stop"}, headers=B)
    assert resp.status == 200
    assert hub.motion.active(clock.now) is None
    assert commands[-1] == ("stop", "headset") and commands.count(("stop", "headset")) == 2


async def test_a_stop_in_the_middle_of_a_concurrent_flood_is_never_refused(client, hub, clock, commands):
    flood = [client.post(MOTION, json={"command": "up"}, headers=A) for _ in range(60)]
    stops = [client.post(MOTION, json={"command": "stop"}, headers=who) for who in (A, B)]
    responses = await asyncio.gather(*flood[:30], *stops, *flood[30:])
    assert [r.status for r in responses[30:32]] == [200, 200]
    assert {r.status for r in responses} <= {200, 409, 429}
    assert commands.count(("stop", "headset")) == 2


async def test_only_valid_commands_are_charged(client, http_config):
    for _ in range(3 * http_config.motion_burst):
        await error_of(await client.post(MOTION, json={"command": "sideways"}, headers=A), 400)
        await error_of(await client.post(MOTION, data=b"{", headers=A | {"Content-Type": "application/json"}), 400)
    assert (await client.post(MOTION, json={"command": "up"}, headers=A)).status == 200


async def test_wearer_actions_face_and_speech_are_limited_per_client(client, http_config, hub):
    for _ in range(http_config.action_burst):
        assert (await client.post("/api/v1/actions/heart", headers=A)).status == 202
    resp = await client.post("/api/v1/actions/heart", headers=A)
    body = await error_of(resp, 429)
    assert "per client" in body["message"] and int(resp.headers["Retry-After"]) >= 1
    ok, jpeg = cv2.imencode(".jpg", np.zeros((8, 8, 3), np.uint8))
    await error_of(await client.put("/api/v1/face", data=jpeg.tobytes(), headers=A | {"Content-Type": "image/jpeg"}), 429)
    assert (await client.post("/api/v1/actions/heart", headers=B)).status == 202
    assert (await client.put("/api/v1/face", data=jpeg.tobytes(), headers=B | {"Content-Type": "image/jpeg"})).status == 200
    wav = _wav(160)
    codes = [(await client.post("/api/v1/speech", data=wav, headers=A | {"Content-Type": "audio/wav"})).status for _ in range(http_config.speech_burst + 1)]
    assert codes == [202] * http_config.speech_burst + [429]


async def test_new_client_ids_from_one_address_do_not_multiply_its_allowance(client, http_config):
    """40 hearts, each from a client id of its own, from one address: the address's bucket (clients_per_address
    times one client's) refuses the rest, as it would a device that invents an id per request."""
    codes = [(await client.post("/api/v1/actions/heart", headers=as_client(f"id{i}"))).status for i in range(40)]
    allowed = http_config.action_burst * http_config.clients_per_address
    assert codes.count(202) == allowed and codes.count(429) == 40 - allowed


def _wav(samples: int) -> bytes:
    from feelium.wav import encode_wav

    return encode_wav(np.zeros(samples, "<i2").tobytes(), 16000)


async def test_motion_is_exclusive_until_taken_over(client, hub, clock, commands):
    assert (await client.post(MOTION, json={"command": "forward"}, headers=A)).status == 200
    body = await error_of(await client.post(MOTION, json={"command": "turn_left"}, headers=B), 409)
    assert body["error"] == "not_in_control" and body["controller"] == "127.0.0.1/A" and body["you"] == "127.0.0.1/B"
    assert "take_over" in body["message"] and 0 < body["lease_remaining_s"] <= 5.0
    assert hub.motion.active(clock.now).name == "forward"  # B's command never reached the flight loop
    resp = await client.post(MOTION, json={"command": "turn_left", "take_over": True}, headers=B)
    assert resp.status == 200 and (await resp.json())["controller"] == "127.0.0.1/B"
    assert hub.motion.active(clock.now).name == "turn_left"
    assert (await error_of(await client.post(MOTION, json={"command": "up"}, headers=A), 409))["controller"] == "127.0.0.1/B"
    state = await (await client.get("/api/v1/state", headers=A)).json()
    assert state["headset_link"]["controller"] == "127.0.0.1/B"
    await error_of(await client.post(MOTION, json={"command": "up", "take_over": "yes"}, headers=A), 400)


async def test_a_stop_from_a_bystander_sticks_and_a_quiet_lease_lapses(client, hub, clock, http_config):
    assert (await client.post(MOTION, json={"command": "forward"}, headers=A)).status == 200
    assert (await client.post(MOTION, json={"command": "stop"}, headers=B)).status == 200
    assert hub.motion.active(clock.now) is None
    await error_of(await client.post(MOTION, json={"command": "forward"}, headers=A), 409)  # not undone by A's refresh
    clock.now += http_config.control_lease_s  # B said nothing more
    assert (await client.post(MOTION, json={"command": "forward"}, headers=A)).status == 200


async def test_clients_without_an_id_are_one_client_per_address(client):
    assert (await client.post(MOTION, json={"command": "up"}, headers=AUTH)).status == 200
    assert (await client.post(MOTION, json={"command": "up"}, headers=AUTH | {"X-Feelium-Client": "bad id!"})).status == 200
    body = await error_of(await client.post(MOTION, json={"command": "up"}, headers=A), 409)
    assert body["controller"] == "127.0.0.1"


# --- point 2: MJPEG slots ------------------------------------------------------------------------------------


@pytest.fixture
async def small_client(aiohttp_client, hub, http_config):  # type: ignore[no-untyped-def]
    config = replace(http_config, max_stream_clients=3, max_streams_per_client=2)
    c = await aiohttp_client(create_app(config, hub, TOKEN))
    c.link = link_of(c.server.app)
    return c


async def test_stream_slots_per_client_and_in_total(small_client, hub):
    hub.front_video.publish(1.0, np.zeros((8, 8), np.uint8))
    url = "/api/v1/video/front.mjpeg"
    a1, a2 = await small_client.get(url, headers=A), await small_client.get(f"{url}?client=A", headers=AUTH)
    assert a1.status == a2.status == 200
    assert "this client" in (await error_of(await small_client.get(url, headers=A), 429))["message"]
    b1 = await small_client.get(url, headers=B)
    assert b1.status == 200
    assert "all 3" in (await error_of(await small_client.get("/api/v1/video/rear.mjpeg", headers=as_client("C")), 429))["message"]
    a1.close()
    for _ in range(100):
        if small_client.link.streams.held_by("127.0.0.1/A") == 1:
            break
        await asyncio.sleep(0.01)
    c1 = await small_client.get(url, headers=as_client("C"))
    assert c1.status == 200
    for r in (a2, b1, c1):
        r.close()


@pytest.mark.parametrize("fps", ["0.001", "0.5", "1e-300"])
async def test_a_tiny_fps_is_refused_and_holds_no_slot(client, hub, fps):
    body = await error_of(await client.get(f"/api/v1/video/front.mjpeg?fps={fps}", headers=A), 400)
    assert "fps must be 0" in body["message"]
    assert client.link.streams.in_use == 0


async def test_a_client_that_never_reads_loses_its_slot(small_client, hub):
    """A raw socket with a tiny receive window asks for the stream and never reads; its slot comes back."""
    rng = np.random.default_rng(1)
    host, port = small_client.server.host, small_client.server.port
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.setblocking(False)
    loop = asyncio.get_running_loop()
    await loop.sock_connect(sock, (host, port))
    await loop.sock_sendall(sock, f"GET /api/v1/video/front.mjpeg HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {TOKEN}\r\n\r\n".encode())
    try:
        released = False
        for i in range(400):  # noise frames (~100 kB JPEGs) at ~100 fps until the stream is dropped
            hub.front_video.publish(float(i), rng.integers(0, 255, (240, 320, 3), np.uint8))
            await asyncio.sleep(0.01)
            if i > 5 and small_client.link.streams.in_use == 0:
                released = True
                break
        assert released, small_client.link.counters
        assert small_client.link.counters["stalled_clients_dropped"] == 1
    finally:
        sock.close()


# --- point 2: bounded input ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "path, raw",
    [
        (MOTION, '{"command": "forward", "hold_ms": 1' + "0" * 400 + "}"),
        (MOTION, '{"command": "forward", "hold_ms": -1' + "0" * 400 + "}"),
        (MOTION, '{"command": "forward", "hold_ms": 1e400}'),
        (MOTION, '{"command": "forward", "hold_ms": 1' + "0" * 5000 + "}"),
        (MOTION, '{"command": "forward", "hold_ms": NaN}'),
        (MOTION, '{"command": "forward", "hold_ms": Infinity}'),
        ("/api/v1/sim/press", '{"x": 1e400, "y": 10}'),
        ("/api/v1/sim/press", '{"x": 1' + "0" * 400 + ', "y": 10}'),
        ("/api/v1/sim/press", '{"x": 10, "y": 65536}'),
        ("/api/v1/actions/guess", '{"word": "' + "x" * 41 + '"}'),
    ],
    ids=["hold-10e400", "hold-minus-10e400", "hold-1e400", "hold-5000-digits", "nan", "infinity", "x-1e400",
         "x-10e400", "y-above-bound", "word-too-long"],
)
async def test_huge_and_non_finite_numbers_are_400(client, hub, path, raw):
    hub.rear_scene = FakeScene()
    await error_of(await client.post(path, data=raw.encode(), headers=A | {"Content-Type": "application/json"}), 400)
    assert hub.rear_scene.calls == [] and hub.motion.accepted == 0


@pytest.mark.parametrize(
    "query",
    ["/api/v1/speech?timeout=0&after=1" + "0" * 400, "/api/v1/speech?timeout=0&after=-1" + "0" * 400,
     "/api/v1/speech/stream?rate=1" + "0" * 400, "/api/v1/speech/stream?rate=nan", "/api/v1/events?timeout=1e400"],
    ids=["after-10e400", "after-minus-10e400", "rate-10e400", "rate-nan", "timeout-1e400"],
)
async def test_huge_numbers_in_a_query_are_400(client, query):
    """An integer too large for a float once reached math.isfinite and was answered 500."""
    body = await error_of(await client.get(query, headers=A), 400)
    assert "query parameter" in body["message"]


@pytest.mark.parametrize(
    "raw",
    ["[" * 5000 + "]" * 5000, '{"command": ' + "[" * 5000 + "]" * 5000 + "}", '{"a":' * 2500 + "1" + "}" * 2500],
    ids=["array", "in-a-field", "objects"],
)
async def test_deep_nesting_is_400(client, raw):
    body = await error_of(await client.post(MOTION, data=raw.encode(), headers=A | {"Content-Type": "application/json"}), 400)
    assert "levels deep" in body["message"]


@pytest.mark.parametrize(
    "data, ctype, status, fragment",
    [
        (b'{"command": "forward"}', "text/plain", 415, "application/json"),  # (a stop is applied anyway: test_api)
        (b'{"command": "forward"}', "application/octet-stream", 415, "application/json"),
        (b'{"command": "forward"}', "application/json; charset=latin-1", 415, "utf-8"),
        (b'{"command": "st\xffop"}', "application/json", 400, "utf-8"),
        (b'\xfe\xff\x00{\x00}', "application/json", 400, "utf-8"),
        ('{"command": "stop"}'.encode("utf-16"), "application/json", 400, "utf-8"),
        (b'{"command": "stop", "pad": "' + b"x" * 20000 + b'"}', "application/json", 413, "limit"),
    ],
    ids=["text-plain", "octet-stream", "latin-1", "invalid-utf8", "utf16-bytes", "utf16-bom", "oversize"],
)
async def test_content_type_encoding_and_size(client, hub, data, ctype, status, fragment):
    body = await error_of(await client.post(MOTION, data=data, headers=A | {"Content-Type": ctype}), status)
    assert fragment in body["message"].lower()
    assert hub.motion.accepted == 0


async def test_an_oversized_chunked_body_is_413(client):
    async def chunks():  # type: ignore[no-untyped-def]
        for _ in range(40):
            yield b"x" * 1024

    await error_of(await client.post(MOTION, data=chunks(), headers=A | {"Content-Type": "application/json"}), 413)


@pytest.mark.parametrize(
    "method, path, status",
    [("GET", "/nope", 404), ("GET", "/static/nope.js", 404), ("GET", "/static/", 404), ("GET", "/api/v1/nope", 404),
     ("POST", "/", 405), ("DELETE", "/api/v1/motion", 405), ("GET", "/api/v1/actions/heart", 405),
     ("POST", "/api/v1/actions/nope", 404), ("GET", "/api/v1/video/nope.mjpeg", 404)],
)  # fmt: skip
async def test_every_404_and_405_is_json(client, method, path, status):
    await error_of(await client.request(method, path, headers=AUTH), status)


async def test_static_files_are_still_served(client):
    resp = await client.get("/static/app.js")
    assert resp.status == 200 and "motion" in await resp.text()


# --- point 2: images -----------------------------------------------------------------------------------------


def _small_jpeg() -> bytes:
    ok, buf = cv2.imencode(".jpg", np.full((16, 16, 3), 90, np.uint8))
    assert ok
    return buf.tobytes()


async def test_an_8000x8000_face_is_refused_from_its_header(client, hub):
    huge = declare_size(_small_jpeg(), 8000, 8000)
    body = await error_of(await client.put("/api/v1/face", data=huge, headers=A | {"Content-Type": "image/jpeg"}), 413)
    assert body["error"] == "image_too_large" and "8000x8000" in body["message"]
    assert hub.face.get() is None


async def test_an_avatar_with_one_oversized_frame_is_refused(client, hub):
    import aiohttp

    form = aiohttp.FormData()
    form.add_field("f0", _small_jpeg(), content_type="image/jpeg", filename="0.jpg")
    form.add_field("f1", declare_size(_small_jpeg(), 4097, 1024), content_type="image/jpeg", filename="1.jpg")
    body = await error_of(await client.put("/api/v1/face", data=form, headers=A), 413)
    assert "frame 1" in body["message"]
    assert hub.face.get() is None


async def test_a_face_without_a_frame_header_is_400(client, hub):
    await error_of(await client.put("/api/v1/face", data=b"\xff\xd8\xff\xe0\x00\x02\xff\xd9", headers=A | {"Content-Type": "image/jpeg"}), 400)


async def test_face_uploads_past_the_daemon_wide_gate_are_refused_before_their_body_is_read(client, hub):
    """While ``max_uploads_in_flight`` bodies are being read, one more upload, from any client id, gets 429 at
    once: ids are free to pick, so only a daemon-wide gate keeps concurrent megabytes off a 512 MB board."""
    link = client.link
    link.uploads_in_flight = link.config.max_uploads_in_flight  # as if that many were being received
    body = await error_of(await client.put("/api/v1/face", data=_small_jpeg(), headers=B | {"Content-Type": "image/jpeg"}), 429)
    assert body["error"] == "uploads_busy" and hub.face.get() is None
    link.uploads_in_flight = 0
    resp = await client.put("/api/v1/face", data=_small_jpeg(), headers=B | {"Content-Type": "image/jpeg"})
    assert resp.status == 200 and link.uploads_in_flight == 0  # released after the read


async def test_a_client_without_a_token_left_is_refused_before_its_face_is_read(client, http_config):
    for _ in range(http_config.action_burst):
        assert (await client.post("/api/v1/actions/heart", headers=A)).status == 202
    not_a_jpeg = b"x" * 100  # would be a 400 if it were read: the 429 comes first
    body = await error_of(await client.put("/api/v1/face", data=not_a_jpeg, headers=A | {"Content-Type": "image/jpeg"}), 429)
    assert "limited" in body["message"]
