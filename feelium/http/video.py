"""Video for the headset: MJPEG streams (one coroutine per client, newest frame always) and single JPEGs.

A client never gets a queue: each loop iteration waits for a frame newer than
the last one it sent, so a slow client simply skips frames. A client whose
socket accepts nothing for ``stream_write_timeout_s`` is dropped, so a
stalled headset cannot pin memory or a coroutine forever.
"""

from __future__ import annotations

import asyncio
import fcntl
import logging
import socket
import struct
import termios

from aiohttp import web

from feelium.http.auth import token_of
from feelium.http.clients import client_of
from feelium.http.clock import CAPTURE_HEADER
from feelium.http.context import ctx
from feelium.http.errors import ApiError
from feelium.http.jpeg import JpegFeed
from feelium.http.open_streams import transport_closer
from feelium.http.params import query_number
from feelium.http.slots import SlotsFull

log = logging.getLogger(__name__)

BOUNDARY = "feeliumframe"
# The kernel send buffer of a stream socket: a few frames in flight over Wi-Fi, not megabytes of stale video
# (Linux autotunes loopback and LAN buffers to MBs, which both delays frames and hides a stalled client).
STREAM_SNDBUF_BYTES = 256 * 1024
# Video in flight (sent, not yet acknowledged by the client's kernel) is capped by [http] stream_inflight_bytes
# before the next frame goes out: a slow or congested client then gets the newest frame when it catches up instead
# of the ~20 frames the send buffer could hold. Polled with SIOCOUTQ (Linux); elsewhere only the write timeout applies.
INFLIGHT_POLL_S = 0.005


def unacked_bytes(sock: socket.socket | None) -> int | None:
    """Bytes in the kernel's send queue of ``sock`` (unsent or unacknowledged), or ``None`` where unknown."""
    if sock is None:
        return None
    try:
        return struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.TIOCOUTQ, b"\0\0\0\0"))[0]
    except (OSError, ValueError):
        return None


async def wait_until_acknowledged(sock: socket.socket | None, limit: int, timeout: float) -> bool:
    """Wait until at most ``limit`` bytes are in flight; ``False`` when the queue did not shrink for ``timeout``."""
    queued = unacked_bytes(sock)
    if queued is None:
        return True
    loop = asyncio.get_running_loop()
    last_progress = loop.time()
    while queued > limit:
        await asyncio.sleep(INFLIGHT_POLL_S)
        now_queued = unacked_bytes(sock)
        if now_queued is None:
            return True
        if now_queued < queued:
            last_progress = loop.time()
        elif loop.time() - last_progress > timeout:
            return False
        queued = now_queued
    return True


def _feed(request: web.Request) -> JpegFeed:
    name = request.match_info["camera"]
    feed = ctx(request).videos.get(name)
    if feed is None:
        raise ApiError(404, f"no camera {name!r}; expected one of {', '.join(ctx(request).videos)}")
    return feed


def part_header(length: int, t: float, seq: int) -> bytes:
    """The MIME part header that precedes one JPEG: its length, capture time ``t`` (daemon clock) and number."""
    return (
        f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {length}\r\n"
        f"{CAPTURE_HEADER}: {t:.6f}\r\nX-Frame-Seq: {seq}\r\n\r\n"
    ).encode("ascii")


async def jpeg(request: web.Request) -> web.Response:
    """The newest frame as one JPEG (for polling clients); 404 until the camera has published one."""
    feed = _feed(request)
    item = await feed.newest()
    if item is None:
        raise ApiError(404, f"no {feed.name} frame yet", "no_frame")
    return web.Response(
        body=item.value,
        content_type="image/jpeg",
        headers={"Cache-Control": "no-store", CAPTURE_HEADER: f"{item.t:.6f}", "X-Frame-Seq": str(item.seq)},
    )


MAX_FPS = 120.0
# The lowest ?fps= a stream may ask for (400 below; 0 = the camera's rate). A stream that writes once an hour
# would hold its slot all that time without ever meeting the write timeout, which only runs while writing.
MIN_FPS = 1.0


async def mjpeg(request: web.Request) -> web.StreamResponse:
    """``multipart/x-mixed-replace`` stream of the newest frames; ``?fps=`` caps the rate.

    A stream holds one of a bounded number of slots (per client and in total) until it ends. A client
    that stops reading loses its slot after ``stream_write_timeout_s`` without progress; ``fps`` has a
    floor so that a stream always writes often enough for that timeout to notice.
    """
    link = ctx(request)
    feed = _feed(request)
    client = client_of(request)
    max_fps = query_number(request, "fps", 0.0, 0.0, MAX_FPS)
    if 0 < max_fps < MIN_FPS:
        raise ApiError(400, f"fps must be 0 (camera rate) or within {MIN_FPS:g}..{MAX_FPS:g}, got {max_fps:g}")
    try:
        link.streams.acquire(client)
    except SlotsFull as exc:
        raise ApiError(429, f"{exc}; close one first", headers={"Retry-After": "1"}) from None
    try:
        with link.open_streams.held(token_of(request), transport_closer(request)):
            return await _stream(request, feed, max_fps)
    finally:
        link.streams.release(client)


async def _stream(request: web.Request, feed: JpegFeed, max_fps: float) -> web.StreamResponse:
    link = ctx(request)
    response = web.StreamResponse(
        headers={
            "Content-Type": f"multipart/x-mixed-replace; boundary={BOUNDARY}",
            "Cache-Control": "no-store",
            "X-Accel-Buffering": "no",
        }
    )
    timeout = link.config.stream_write_timeout_s
    feed.clients += 1
    link.count("video_streams")
    sock = request.transport.get_extra_info("socket") if request.transport is not None else None
    try:
        if sock is not None:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, STREAM_SNDBUF_BYTES)
        await response.prepare(request)
        seq = 0
        loop = asyncio.get_running_loop()
        next_at = 0.0
        while True:
            item = await feed.next_after(seq, timeout=link.config.keepalive_s)
            if item is None:
                continue
            seq = item.seq
            part = part_header(len(item.value), item.t, item.seq) + item.value + b"\r\n"
            try:
                async with asyncio.timeout(timeout):
                    await response.write(part)
                inflight = link.config.stream_inflight_bytes
                delivered = inflight == 0 or await wait_until_acknowledged(sock, inflight, timeout)
            except asyncio.TimeoutError:
                delivered = False
            if not delivered:
                link.count("stalled_clients_dropped")
                log.info("dropping stalled %s stream client %s", feed.name, request.remote)
                if request.transport is not None:
                    request.transport.abort()
                break
            link.count("video_frames_sent")
            if max_fps > 0:
                next_at = max(next_at + 1.0 / max_fps, loop.time())
                await asyncio.sleep(next_at - loop.time())
    except (ConnectionResetError, ConnectionError):
        pass
    finally:
        feed.clients -= 1
    return response
