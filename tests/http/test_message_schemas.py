"""Every streamed message the daemon really sends validates against its schema in the OpenAPI document.

Messages are collected from the live sim daemon over the WebSocket and SSE (touch from a simulated press,
wearer actions and the interaction engine's answers, a reset, speech stream frames), and from the test
app for what the sim does not produce on demand (presence, a drawing stroke with points).
"""

from __future__ import annotations

import asyncio
import json
from typing import Any

import aiohttp
import jsonschema
import pytest
from referencing import Registry, Resource
from referencing.jsonschema import DRAFT202012

from feelium.events import ContactShape, InteractionEvent, PresenceEvent, TouchEvent
from feelium.http.openapi import openapi_document
from feelium.http.speech_stream import decode_frame

from tests.http.http_support import AUTH

DOC = openapi_document()
_REGISTRY = Registry().with_resource("urn:feelium-api", Resource.from_contents(DOC, default_specification=DRAFT202012))


def check(name: str, instance: Any) -> None:
    """Validate ``instance`` against ``components/schemas/<name>`` (refs resolved inside the document)."""
    schema = {"$ref": f"urn:feelium-api#/components/schemas/{name}"}
    jsonschema.Draft202012Validator(schema, registry=_REGISTRY).validate(instance)


def test_the_schemas_refuse_what_the_daemon_must_not_send() -> None:
    good = {"seq": 3, "epoch": "9f3c01ab", "type": "wearer_action", "event": {"action": "heart", "t": 1.0}}
    check("Event", good)
    for bad in (
        good | {"type": "touch"},  # a touch needs the touch fields
        good | {"event": {"action": "wave", "t": 1.0}},
        good | {"event": {"action": "heart", "t": 1.0, "surprise": 1}},  # undocumented fields are refused
        good | {"epoch": "x"},
    ):
        with pytest.raises(jsonschema.ValidationError):
            check("Event", bad)
    every_stream_op = [op for item in DOC["paths"].values() for op in item.values() if op.get("x-streaming")]
    assert all("x-sse-events" in op or "x-websocket-messages" in op or op["operationId"] == "videoMjpeg" for op in every_stream_op)
    assert set(DOC["components"]["schemas"]["Error"]["x-error-codes"]) >= {"bad_request", "unauthorized", "too_many_requests"}


def test_a_touch_event_with_its_contact_shape_matches_its_schema() -> None:
    shape = ContactShape("palm", 7800.0, 160.0, 78.0, 2.05, 91.0)
    event = TouchEvent(3, "up", "hold", 2.5, 300.0, 210.0, 0.46, 0.42, 0.66, 45000, 0.6, shape).to_json()
    check("TouchEvent", event)
    check("TouchEvent", event | {"contact_area_mm2": None, "major_mm": None, "minor_mm": None})  # scale unknown
    with pytest.raises(jsonschema.ValidationError):
        check("TouchEvent", event | {"contact": "elbow"})


async def _collect_ws(session: aiohttp.ClientSession, url: str, want: set[str], out: list[dict]) -> None:
    async with session.ws_connect(url) as ws:
        async for msg in ws:
            item = json.loads(msg.data)
            out.append(item)
            if want <= {m["type"] for m in out}:
                return


async def _collect_sse(session: aiohttp.ClientSession, url: str, want: set[str], out: list[tuple[str, str, dict]]) -> None:
    async with session.get(url) as resp:
        fields: dict[str, str] = {}
        async for raw in resp.content:
            line = raw.decode().rstrip("\n")
            if line == "":
                if "data" in fields:
                    out.append((fields.get("id", ""), fields.get("event", ""), json.loads(fields["data"])))
                    if want <= {e for _, e, _ in out}:
                        return
                fields = {}
            elif not line.startswith(":"):
                key, _, value = line.partition(": ")
                fields[key] = value


@pytest.mark.slow
async def test_live_websocket_and_sse_messages_match_their_schemas(live) -> None:
    want = {"reset", "touch", "wearer_action", "interaction"}
    async with aiohttp.ClientSession(headers=live.auth) as session:
        async with session.get(f"{live.api}/events", params={"timeout": 0}) as resp:
            batch = await resp.json()
        check("EventBatch", batch)
        stale = "00000000:1"  # another run's epoch: a reset comes first
        ws_items: list[dict] = []
        sse_items: list[tuple[str, str, dict]] = []
        ws_url = f"{live.api.replace('http', 'ws', 1)}/events/ws?after={stale}"
        tasks = [
            asyncio.create_task(_collect_ws(session, ws_url, want, ws_items)),
            asyncio.create_task(_collect_sse(session, f"{live.api}/events/stream?after={stale}", want, sse_items)),
        ]
        await asyncio.sleep(0.3)
        async with session.get(f"{live.api}/sim") as resp:
            sim = await resp.json()
        async with session.post(f"{live.api}/sim/press", json={"x": sim["width"] / 2, "y": sim["height"] / 2}) as resp:
            assert resp.status == 202
        for action, body in (("shimmer", None), ("heart", None), ("guess", {"word": "cat"})):
            async with session.post(f"{live.api}/actions/{action}", json=body) as resp:
                assert resp.status == 202
        try:
            await asyncio.wait_for(asyncio.gather(*tasks), 20)
        finally:
            async with session.post(f"{live.api}/sim/release"):
                pass
            for task in tasks:
                task.cancel()
        async with session.get(f"{live.api}/state") as resp:
            check("State", await resp.json())
    assert ws_items[0]["type"] == "reset" and sse_items[0][1] == "reset"
    for item in ws_items:
        check("StreamMessage", item)
    for sse_id, sse_event, item in sse_items:
        check("StreamMessage", item)
        assert sse_event == item["type"] and sse_id == f"{item['epoch']}:{item['seq']}"
        assert DOC["paths"]["/events/stream"]["get"]["x-sse-events"][sse_event]


@pytest.mark.slow
async def test_live_speech_stream_messages_match_their_schemas(live) -> None:
    async with aiohttp.ClientSession(headers=live.auth) as session:
        async with session.ws_connect(f"{live.api.replace('http', 'ws', 1)}/speech/stream") as ws:
            hello = await ws.receive_json(timeout=5)
            frames = [decode_frame((await ws.receive(timeout=5)).data) for _ in range(3)]
            await ws.send_bytes(b"\x01")
            message = await ws.receive(timeout=5)
            while message.type == aiohttp.WSMsgType.BINARY:  # frames go on streaming until the notice comes
                message = await ws.receive(timeout=5)
            notice = message.json()
        async with session.get(f"{live.api}/clock") as resp:
            now = (await resp.json())["t"]
    check("SpeechStreamHello", hello)
    check("SpeechStreamNotice", notice)
    for frame in frames:
        check("SpeechFrameHeader", frame.header_json())
        assert 0 <= now - frame.capture_t < 5  # on the one clock of GET /clock
    assert [f.seq for f in frames] == list(range(frames[0].seq, frames[0].seq + 3))


async def test_presence_and_drawing_messages_from_the_app_match_their_schemas(client, hub) -> None:
    """What the sim does not produce on demand, through the same serialisers and transports."""
    events = [
        PresenceEvent("approach", 100.0, 15.5, 11.0, -4.2, 1.5, 12, 6.25),
        PresenceEvent("leave", 101.0, float("nan"), float("nan"), float("nan"), float("nan"), 0, float("nan")),
        InteractionEvent("drawing", "stroke", 100.5, 12.0, 30.0, "belly", {"stroke": 1, "points": [[0.1, 0.2], [0.15, 0.25]]}),
        InteractionEvent("drawing", "end", 102.0, detail={"reason": "idle", "word": "cat"}),
        InteractionEvent("hug", "start", 102.5, detail={"area": 5400}),
    ]
    async with client.ws_connect("/api/v1/events/ws", headers=AUTH) as ws:
        await asyncio.sleep(0.05)
        for event in events:
            hub.bus.publish(event)
        got = [await ws.receive_json(timeout=2) for _ in events]
    for item in got:
        check("StreamMessage", item)
    assert [item["type"] for item in got] == ["presence", "presence", "interaction", "interaction", "interaction"]
    resp = await client.get("/api/v1/events?after=0&timeout=0", headers=AUTH)
    check("EventBatch", await resp.json())
    resp = await client.get("/api/v1/speech/stream", headers=AUTH)  # not an upgrade: the Error schema
    check("Error", await resp.json())
