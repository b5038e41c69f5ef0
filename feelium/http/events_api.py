"""Touch, presence and interaction events three ways: long-poll, Server-Sent Events and WebSocket.

All three read the same ring and send the same envelopes
(``{"seq", "epoch", "type", "event"}``), so a client can switch transports
and keep its place with the resume token ``EPOCH:SEQ``.
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from aiohttp import WSMsgType, web

from feelium.http.auth import token_of
from feelium.http.clients import client_of
from feelium.http.context import LinkContext, ctx
from feelium.http.errors import ApiError
from feelium.http.message_budget import BUDGETED, MessageBudget
from feelium.http.motion_api import motion_message
from feelium.http.open_streams import transport_closer, ws_closer
from feelium.http.params import query_number
from feelium.http.ring import Catchup, parse_resume, resume_token
from feelium.http.slots import SlotsFull

log = logging.getLogger(__name__)

MAX_SEQ = 2**53
MAX_SOCKET_MESSAGE_BYTES = 4096  # a motion command is ~100 bytes; larger closes the socket (1009)


def _after(request: web.Request, header_value: str | None = None) -> tuple[str | None, int] | None:
    """Where the client resumes: ``(epoch, seq)`` from ``Last-Event-ID`` or ``?after=`` (``EPOCH:SEQ``, or a
    bare ``SEQ`` taken as this run's); ``None`` = only new events."""
    name, text = ("Last-Event-ID", header_value) if header_value else ("after", request.query.get("after", ""))
    if text == "":
        return None
    try:
        return parse_resume(text, MAX_SEQ)
    except ValueError as exc:
        raise ApiError(400, f"{name} must be EPOCH:SEQ (or an integer sequence) as the server sent it, got {text[:40]!r}: {exc}") from None


def catchup_body(link: LinkContext, catchup: Catchup) -> dict[str, Any]:
    ring = link.events.ring
    body: dict[str, Any] = {
        "events": catchup.events, "last_seq": catchup.last_seq, "epoch": ring.epoch,
        "resume": resume_token(ring.epoch, catchup.last_seq), "reset": catchup.reset,
    }
    if catchup.reset:
        body["state"] = link.hub.state.snapshot()
    return body


def reset_message(link: LinkContext, catchup: Catchup) -> dict[str, Any]:
    """What a streaming client gets instead of events it cannot have: the state now, then only new events."""
    return {"seq": catchup.last_seq, "epoch": link.events.ring.epoch, "type": "reset", "event": {"state": link.hub.state.snapshot()}}


async def long_poll(request: web.Request) -> web.Response:
    """``GET /events?after=SEQ&timeout=S``: events after SEQ, waiting up to S seconds for the first."""
    link = ctx(request)
    after = _after(request)
    timeout = min(query_number(request, "timeout", 0.0, 0.0, 300.0), link.config.longpoll_max_s)
    epoch, seq = (None, link.events.ring.last_seq) if after is None else after
    catchup = await link.events.wait_after(seq, timeout, epoch)
    return web.json_response(catchup_body(link, catchup), headers={"Cache-Control": "no-store"})


def sse_message(item: dict[str, Any]) -> bytes:
    """One SSE message whose ``id`` is the resume token, so ``Last-Event-ID`` resumes after it."""
    return f"id: {resume_token(item['epoch'], item['seq'])}\nevent: {item['type']}\ndata: {json.dumps(item, separators=(',', ':'))}\n\n".encode()


async def sse(request: web.Request) -> web.StreamResponse:
    """``GET /events/stream``: Server-Sent Events; resumes after ``Last-Event-ID`` (or ``?after=``)."""
    link = ctx(request)
    after = _after(request, request.headers.get("Last-Event-ID"))
    response = web.StreamResponse(
        headers={"Content-Type": "text/event-stream", "Cache-Control": "no-store", "X-Accel-Buffering": "no"}
    )
    client = client_of(request)
    with event_slot(link, client), link.open_streams.held(token_of(request), transport_closer(request)):
        await response.prepare(request)
        await _serve_sse(request, response, link, after)
    return response


@contextmanager
def event_slot(link: LinkContext, client: str) -> Iterator[None]:
    """One of the bounded event-stream slots (429 without one) for as long as the stream lives."""
    try:
        link.event_streams.acquire(client)
    except SlotsFull as exc:
        raise ApiError(429, f"{exc}; close one first", headers={"Retry-After": "1"}) from None
    try:
        yield
    finally:
        link.event_streams.release(client)


async def _serve_sse(request: web.Request, response: web.StreamResponse, link: LinkContext, after: Any) -> None:
    timeout = link.config.stream_write_timeout_s
    epoch, seq = (None, link.events.ring.last_seq) if after is None else after
    link.count("event_clients")
    try:
        async with asyncio.timeout(timeout):
            await response.write(b"retry: 1000\n\n")
        while True:
            catchup = await link.events.wait_after(seq, link.config.keepalive_s, epoch)
            epoch = None  # from here on the client follows this run's numbers
            if catchup.reset:
                async with asyncio.timeout(timeout):
                    await response.write(sse_message(reset_message(link, catchup)))
            if catchup.events or catchup.reset:
                payload = b"".join(sse_message(item) for item in catchup.events)
                if payload:
                    async with asyncio.timeout(timeout):
                        await response.write(payload)
                seq = catchup.last_seq
            else:
                async with asyncio.timeout(timeout):
                    await response.write(b": keepalive\n\n")
    except asyncio.TimeoutError:
        link.count("stalled_clients_dropped")
        if request.transport is not None:
            request.transport.abort()
    except (ConnectionResetError, ConnectionError):
        pass
    finally:
        link.count("event_clients", -1)


async def websocket(request: web.Request) -> web.StreamResponse:
    """``GET /events/ws``: the same envelopes as WebSocket text messages; ``?after=`` to resume. The client may
    send motion commands on it (:func:`motion_message`): a headset refreshing the dead man at 20 Hz then pays
    a message, not an HTTP request, per refresh."""
    link = ctx(request)
    after = _after(request)
    # autoping off: pings and pongs reach the reader, so they count against the message budget too
    ws = web.WebSocketResponse(heartbeat=link.config.keepalive_s, max_msg_size=MAX_SOCKET_MESSAGE_BYTES, autoping=False)
    if not ws.can_prepare(request).ok:
        raise ApiError(400, "expected a WebSocket upgrade request")
    client = client_of(request)
    with event_slot(link, client), link.open_streams.held(token_of(request), ws_closer(ws)):
        await ws.prepare(request)
        await _serve_websocket(ws, link, client, after, transport_closer(request))
    return ws


async def _serve_websocket(
    ws: web.WebSocketResponse, link: LinkContext, client: str, after: Any, cut_off: Callable[[], None]
) -> None:
    timeout = link.config.stream_write_timeout_s
    epoch, seq = (None, link.events.ring.last_seq) if after is None else after
    link.count("event_clients")
    budget = MessageBudget(link.config.socket_messages_per_s, int(2 * link.config.socket_messages_per_s), link.hub.clock())

    async def drain_incoming() -> None:
        """Motion commands are answered in turn; anything else is read and ignored (keeps pings and close working).
        A client over its message budget is disconnected; each message yields to the loop (see MessageBudget)."""
        async for msg in ws:
            if msg.type == WSMsgType.ERROR:
                return
            if msg.type in BUDGETED and not budget.allows(link.hub.clock()):
                link.count("socket_floods_closed")
                cut_off()  # no close handshake: waiting for it, the loop would go on parsing the flood
                return
            await asyncio.sleep(0)
            if msg.type == WSMsgType.PING:
                await ws.pong(msg.data)
                continue
            text = msg.data if msg.type == WSMsgType.TEXT else msg.data.decode("utf-8", "replace") if msg.type == WSMsgType.BINARY else None
            if text is not None and (reply := motion_message(link, client, text)) is not None:  # binary JSON too
                try:  # the command is applied already; a client that reads nothing is dropped as a stalled stream
                    async with asyncio.timeout(timeout):
                        await ws.send_json(reply)
                except (asyncio.TimeoutError, ConnectionError):
                    link.count("stalled_clients_dropped")
                    return

    reader = asyncio.create_task(drain_incoming())
    try:
        while not ws.closed and not reader.done():
            catchup = await link.events.wait_after(seq, link.config.keepalive_s, epoch)
            epoch = None
            if catchup.reset:
                async with asyncio.timeout(timeout):
                    await ws.send_json(reset_message(link, catchup))
            for item in catchup.events:
                async with asyncio.timeout(timeout):
                    await ws.send_json(item)
            seq = catchup.last_seq
    except asyncio.TimeoutError:
        link.count("stalled_clients_dropped")
    except (ConnectionResetError, ConnectionError):
        pass
    finally:
        link.count("event_clients", -1)
        reader.cancel()
        if not ws.closed:
            await ws.close()
