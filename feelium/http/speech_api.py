"""``GET /speech/stream``: room audio to the wearer as binary WebSocket frames, the wearer's speech back in.

One socket replaces about 25 long-polls (``GET /speech``) and 5-10 uploads
(``POST /speech``) a second. Out: every captured chunk as one frame
(:mod:`feelium.http.speech_stream`), sent when it is captured, dropped (never
queued) while the client's socket holds more than ``speech_stream_backlog_ms``.
In: binary messages of PCM16, under the same per-client rate limit and size
limit as ``POST /speech``; a refused message is dropped and the client told
(at most once a second) in a text ``notice``.
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import Callable

from aiohttp import WSMsgType, web

from feelium.events import SpeechIn
from feelium.http.auth import token_of
from feelium.http.clients import client_of
from feelium.http.message_budget import BUDGETED, MessageBudget
from feelium.http.open_streams import transport_closer, ws_closer
from feelium.http.context import LinkContext, ctx
from feelium.http.errors import ApiError
from feelium.http.events_api import MAX_SEQ
from feelium.http.params import query_number
from feelium.http.slots import SlotsFull
from feelium.http.speech_stream import (
    FRAME_VERSION, HEADER_BYTES, BacklogGate, SpeechFrame, encode_frame, incoming_pcm,
)  # fmt: skip
from feelium.http.video import unacked_bytes

log = logging.getLogger(__name__)

MIN_RATE, MAX_RATE = 8000, 48000
NOTICE_EVERY_S = 1.0  # a flooding client gets one notice a second, not one per refused message


async def stream(request: web.Request) -> web.StreamResponse:
    """Open a speech stream (one slot per socket, bounded per client and in total)."""
    link = ctx(request)
    client = client_of(request)
    target = link.speech_settings.sample_rate
    start = int(query_number(request, "after", link.speech.last_seq, 0, MAX_SEQ, integer=True))
    in_rate = int(query_number(request, "rate", target, MIN_RATE, MAX_RATE, integer=True))
    ws = web.WebSocketResponse(heartbeat=link.config.keepalive_s, max_msg_size=link.config.max_speech_bytes, compress=False,
                               autoping=False)  # pings count against the message budget (MessageBudget)
    if not ws.can_prepare(request).ok:
        raise ApiError(400, "expected a WebSocket upgrade request")
    try:
        link.speech_streams.acquire(client)
    except SlotsFull as exc:
        raise ApiError(429, f"{exc}; close one first", headers={"Retry-After": "1"}) from None
    link.count("speech_streams_opened")
    try:
        with link.open_streams.held(token_of(request), ws_closer(ws)):
            await ws.prepare(request)
            await _serve(request, ws, link, client, min(start, link.speech.last_seq), in_rate)
    except (ConnectionResetError, ConnectionError):
        pass
    finally:
        link.speech_streams.release(client)
        if not ws.closed:
            await ws.close()
    return ws


async def _serve(request: web.Request, ws: web.WebSocketResponse, link: LinkContext, client: str, seq: int, in_rate: int) -> None:
    timeout = link.config.stream_write_timeout_s
    target = link.speech_settings.sample_rate
    await asyncio.wait_for(ws.send_str(json.dumps({
        "type": "hello", "version": FRAME_VERSION, "header_bytes": HEADER_BYTES, "format": "pcm16le", "channels": 1,
        "rate": target, "in_rate": in_rate, "after": seq, "max_in_bytes": link.config.max_speech_bytes,
        "in_rate_per_s": link.config.speech_rate_per_s,
    })), timeout)  # fmt: skip
    reader = asyncio.create_task(_receive(ws, link, client, in_rate, transport_closer(request)))
    sock = request.transport.get_extra_info("socket") if request.transport is not None else None
    backlog_bytes = 2 * target * link.config.speech_stream_backlog_ms // 1000
    gate = BacklogGate(backlog_bytes, timeout)
    loop = asyncio.get_running_loop()
    dropped, previous = 0, None
    try:
        while not ws.closed and not reader.done():
            for number, chunk in await link.speech.wait_numbered_after(seq, link.config.keepalive_s):
                seq = number
                if previous is not None and number > previous + 1:
                    dropped += number - previous - 1  # fell out of the shared feed before this stream got to it
                previous = number
                unacked = unacked_bytes(sock)
                transport = request.transport
                backlog = None if unacked is None or transport is None else unacked + transport.get_write_buffer_size()
                decision = gate.decide(backlog, loop.time())
                if decision == "close":
                    link.count("stalled_clients_dropped")
                    log.info("dropping stalled speech stream client %s", client)
                    if transport is not None:
                        transport.abort()
                    return
                if decision == "drop":
                    dropped += 1
                    link.count("speech_frames_dropped")
                    continue
                frame = SpeechFrame(number, chunk.rate, chunk.t, dropped, chunk.pcm)
                async with asyncio.timeout(timeout):
                    await ws.send_bytes(encode_frame(frame))
                link.count("speech_frames_sent")
    except asyncio.TimeoutError:
        link.count("stalled_clients_dropped")
        if request.transport is not None:
            request.transport.abort()
    finally:
        reader.cancel()


async def _receive(ws: web.WebSocketResponse, link: LinkContext, client: str, in_rate: int, cut_off: Callable[[], None]) -> None:
    """The wearer's speech: each binary message is one chunk for the speaker; text messages are ignored."""
    try:
        await _receive_chunks(ws, link, client, in_rate, cut_off)
    except (asyncio.TimeoutError, ConnectionError):
        pass  # a client that neither reads nor closes: the writer's gate or the heartbeat ends the stream


async def _receive_chunks(
    ws: web.WebSocketResponse, link: LinkContext, client: str, in_rate: int, cut_off: Callable[[], None]
) -> None:
    target = link.speech_settings.sample_rate
    last_notice = -float("inf")
    refused = 0
    budget = MessageBudget(link.config.socket_messages_per_s, int(2 * link.config.socket_messages_per_s), link.hub.clock())
    async for msg in ws:
        if msg.type == WSMsgType.ERROR:
            return
        if msg.type in BUDGETED and not budget.allows(link.hub.clock()):
            link.count("socket_floods_closed")
            cut_off()  # no close handshake: waiting for it, the loop would go on parsing the flood
            return
        await asyncio.sleep(0)  # a burst of buffered messages must not hold the loop (MessageBudget)
        if msg.type == WSMsgType.PING:
            await ws.pong(msg.data)
            continue
        if msg.type != WSMsgType.BINARY:
            continue
        now = link.hub.clock()
        error, message = None, ""
        try:
            pcm = incoming_pcm(msg.data, in_rate, target)
        except ValueError as exc:
            error, message = "bad_request", str(exc)
            link.count("speech_stream_in_bad")
        else:
            if link.speech_limit.take(client, now):
                link.hub.bus.publish(SpeechIn(pcm, target, now))
                link.count("speech_chunks_in")
                continue
            error, message = "too_many_requests", f"speech chunks are limited to {link.speech_limit.rate:g}/s per client"
        refused += 1
        if now - last_notice >= NOTICE_EVERY_S:
            last_notice = now
            notice = {"type": "notice", "error": error, "message": message, "refused_in": refused}
            await asyncio.wait_for(ws.send_str(json.dumps(notice)), link.config.stream_write_timeout_s)
