"""Three headset clients over loopback, in their own process so their CPU is not charged to the daemon.

- ``mjpeg``: reads ``front.mjpeg`` (what the wearer sees) and counts frames;
- ``events``: an SSE stream (touches, presence, answers);
- ``speech``: the speech WebSocket both ways, as the native app uses it (``docs/api.md``): the room audio
  streamed out as it is captured, the wearer's speech in (200 ms chunks, 5 per second);
- ``motion``: a motion command at 20 Hz on an absolute schedule, as a message on the events WebSocket
  (``websocket``, the default: what a headset that already holds that socket does) or as ``POST /motion``
  (``http``), a wearer action every 2 s, and once at the start a looping face video (``PUT /face``, 12 fps avatar).

``python -m feelium.lab.daemon.headset BASE_URL TOKEN SECONDS [websocket|http]`` prints one JSON line of counts
and rates.
"""

from __future__ import annotations

import asyncio
import json
import sys
import time
from collections.abc import Awaitable, Callable
from typing import Any

import aiohttp
import cv2
import numpy as np


MOTION_HZ = 20.0
SPEECH_CHUNK_S = 0.2
SPEECH_RATE = 16000
ACTION_EVERY_S = 2.0
FACE_FRAMES = 24
FACE_FPS = 12
MOTION_TRANSPORTS = ("websocket", "http")
MOTION_BODY = {"command": "turn_left", "hold_ms": 300}


async def mjpeg(session: aiohttp.ClientSession, base: str, until: float) -> dict[str, Any]:
    """Frames of the front stream received before ``until`` (each part carries one ``X-Frame-Seq`` header)."""
    frames, tail = 0, b""
    async with session.get(f"{base}/video/front.mjpeg") as response:
        async for chunk in response.content.iter_any():
            data = tail + chunk
            frames += data.count(b"X-Frame-Seq")
            tail = data[-16:]
            frames -= tail.count(b"X-Frame-Seq")  # counted again with the next chunk
            if time.monotonic() >= until:
                break
    return {"frames": frames}


async def events(session: aiohttp.ClientSession, base: str, until: float) -> dict[str, Any]:
    """Events from the SSE stream, by type."""
    counts: dict[str, int] = {}
    async with session.get(f"{base}/events/stream") as response:
        while time.monotonic() < until:
            try:
                line = await asyncio.wait_for(response.content.readline(), max(0.01, until - time.monotonic()))
            except asyncio.TimeoutError:
                break
            if line.startswith(b"event:"):
                kind = line[6:].strip().decode()
                counts[kind] = counts.get(kind, 0) + 1
    return {"by_type": counts, "events": sum(counts.values())}


async def speech(session: aiohttp.ClientSession, base: str, until: float) -> dict[str, Any]:
    """Room audio frames received and wearer chunks sent over one ``/speech/stream`` WebSocket."""
    pcm = (1000 * np.sin(np.arange(int(SPEECH_RATE * SPEECH_CHUNK_S)) / 5.0)).astype("<i2").tobytes()
    frames = data = sent = 0
    url = f"{base.replace('http', 'ws', 1)}/speech/stream"
    async with session.ws_connect(url, params={"rate": SPEECH_RATE}) as ws:

        async def send() -> None:
            nonlocal sent
            start = time.monotonic()
            while time.monotonic() < until:
                await ws.send_bytes(pcm)
                sent += 1
                await asyncio.sleep(max(0.0, start + sent * SPEECH_CHUNK_S - time.monotonic()))

        sender = asyncio.create_task(send())
        try:
            while (left := until - time.monotonic()) > 0:
                try:
                    message = await ws.receive(timeout=left)
                except asyncio.TimeoutError:
                    break
                if message.type == aiohttp.WSMsgType.BINARY:
                    frames += 1
                    data += len(message.data)
                elif message.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.ERROR):
                    break
        finally:
            sender.cancel()
    return {"frames_out": frames, "bytes_out": data, "chunks_in": sent}


def _face_video() -> aiohttp.FormData:
    """A face whose every pixel changes from frame to frame, as a live face video's does (head motion, sensor
    noise): a drifting texture under a pulsing disc. A flat background would change only around the disc and
    flatter the projector's tiled warp, which re-warps only what changed."""
    form = aiohttp.FormData()
    texture = cv2.GaussianBlur(np.random.default_rng(1).integers(0, 80, (400, 520, 3), np.uint8), (0, 0), 3)
    for i in range(FACE_FRAMES):
        dx, dy = int(20 + 15 * np.sin(i / 4)), int(20 + 15 * np.cos(i / 5))
        image = cv2.add(texture[dy : dy + 360, dx : dx + 480], 40)
        cv2.circle(image, (240, 180), 80 + 4 * (i % 6), (90, 140, 220), -1)
        form.add_field(f"f{i}", cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])[1].tobytes(), content_type="image/jpeg", filename=f"f{i}.jpg")
    return form


async def _motion_over_http(session: aiohttp.ClientSession, base: str) -> Callable[[], Awaitable[bool]]:
    async def send() -> bool:
        async with session.post(f"{base}/motion", json=MOTION_BODY) as response:
            return response.status == 200

    return send


async def motion(session: aiohttp.ClientSession, base: str, until: float, transport: str = "websocket") -> dict[str, Any]:
    """Motion at 20 Hz; a command that starts more than one period after it was due is late. The round trip is
    from sending a command to its answer (the HTTP response, or the WebSocket's ``motion_reply``)."""
    async with session.put(f"{base}/face", params={"fps": FACE_FPS}, data=_face_video()) as response:
        face_status = response.status
    if transport == "websocket":
        async with session.ws_connect(f"{base.replace('http', 'ws', 1)}/events/ws") as ws:
            return await _drive(session, base, until, _motion_over_socket(ws), face_status, transport)
    return await _drive(session, base, until, await _motion_over_http(session, base), face_status, transport)


def _motion_over_socket(ws: aiohttp.ClientWebSocketResponse) -> Callable[[], Awaitable[bool]]:
    sent = 0

    async def send() -> bool:
        nonlocal sent
        sent += 1
        await ws.send_str(json.dumps({"type": "motion", "id": sent} | MOTION_BODY))
        while True:  # events arrive on the same socket: skip them up to this command's reply
            message = await ws.receive()
            if message.type != aiohttp.WSMsgType.TEXT:
                raise ConnectionError(f"events WebSocket ended: {message.type}")
            reply = json.loads(message.data)
            if reply.get("type") == "motion_reply" and reply.get("id") == sent:
                return bool(reply["status"] == 200)

    return send


async def _drive(
    session: aiohttp.ClientSession, base: str, until: float, send: Callable[[], Awaitable[bool]], face_status: int, transport: str
) -> dict[str, Any]:
    period = 1.0 / MOTION_HZ
    start = time.monotonic()
    sent = late = refused = actions = 0
    rtts: list[float] = []
    while (now := time.monotonic()) < until:
        due = start + sent * period
        if now > due + period:
            late += 1
        began = time.monotonic()
        refused += not await send()
        rtts.append(time.monotonic() - began)
        sent += 1
        if sent % round(MOTION_HZ * ACTION_EVERY_S) == 0:
            async with session.post(f"{base}/actions/heart") as response:
                actions += response.status == 202
        await asyncio.sleep(max(0.0, start + sent * period - time.monotonic()))
    elapsed = time.monotonic() - start
    return {
        "transport": transport, "sent": sent, "late": late, "refused": refused, "rate_hz": round(sent / elapsed, 2),
        "target_hz": MOTION_HZ,
        "rtt_ms_p50": round(1000 * float(np.percentile(rtts, 50)), 2) if rtts else None,
        "rtt_ms_p99": round(1000 * float(np.percentile(rtts, 99)), 2) if rtts else None,
        "actions": actions, "face_status": face_status,
    }


async def run(base: str, token: str, seconds: float, motion_transport: str = "websocket") -> dict[str, Any]:
    until = time.monotonic() + seconds
    headers = {"Authorization": f"Bearer {token}"}
    timeout = aiohttp.ClientTimeout(total=None, sock_read=seconds + 5)
    async with aiohttp.ClientSession(headers=headers, timeout=timeout) as session:
        start = time.monotonic()
        video, stream, audio, moves = await asyncio.gather(
            mjpeg(session, base, until), events(session, base, until), speech(session, base, until), motion(session, base, until, motion_transport)
        )
        elapsed = time.monotonic() - start
    video["fps"] = round(video["frames"] / elapsed, 2)
    return {"seconds": round(elapsed, 2), "mjpeg": video, "events": stream, "speech": audio, "motion": moves}


def main() -> None:
    base, token, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    transport = sys.argv[4] if len(sys.argv) > 4 else "websocket"
    if transport not in MOTION_TRANSPORTS:
        sys.exit(f"motion transport must be one of {', '.join(MOTION_TRANSPORTS)}, got {transport!r}")
    print(json.dumps(asyncio.run(run(base, token, seconds, transport))), flush=True)


if __name__ == "__main__":
    main()
