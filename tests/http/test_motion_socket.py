"""Motion commands on the events WebSocket obey POST /motion's rules: stop wins, validation, the lease, rate limits."""

from __future__ import annotations

import json
from typing import Any

import pytest
from jsonschema import Draft202012Validator

from feelium.http.openapi import openapi_document
from tests.http.test_abuse import A, B

WS = "/api/v1/events/ws"
MOTION = "/api/v1/motion"


class Steering:
    """One WebSocket client sending motion commands and reading their replies (events in between are skipped)."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.sent = 0

    async def send(self, **fields: Any) -> dict[str, Any]:
        self.sent += 1
        await self.ws.send_str(json.dumps({"type": "motion", "id": self.sent} | fields))
        while True:
            message = json.loads((await self.ws.receive(timeout=5)).data)
            if message.get("type") == "motion_reply":
                assert message["id"] == self.sent
                return message


@pytest.fixture
def http_config(http_config):  # type: ignore[no-untyped-def]
    """These tests send more messages at one instant than the per-socket budget allows (tested on its own below)."""
    from dataclasses import replace

    return replace(http_config, socket_messages_per_s=1000.0)


@pytest.fixture
def reply_schema():  # type: ignore[no-untyped-def]
    document = openapi_document()
    schema = {"$ref": "#/components/schemas/MotionReply", "components": document["components"]}
    return Draft202012Validator(schema)


async def test_a_command_on_the_socket_reaches_the_dead_man_slot_and_answers_like_post(client, hub, clock, reply_schema):
    async with client.ws_connect(WS, headers=A) as ws:
        reply = await Steering(ws).send(command="forward", hold_ms=300)
    reply_schema.validate(reply)
    assert reply["status"] == 200 and reply["body"]["accepted"] == "forward" and reply["body"]["controller"] == "127.0.0.1/A"
    active = hub.motion.active(clock.now)
    assert active.name == "forward" and active.source == "headset"
    assert active.expires_at == pytest.approx(clock.now + 0.3)
    state = await (await client.get("/api/v1/state", headers=A)).json()
    assert state["headset_link"]["last_motion_age_s"] == 0.0 and state["headset_link"]["controller"] == "127.0.0.1/A"


async def test_invalid_commands_are_400_and_not_charged(client, hub, clock, http_config, reply_schema):
    async with client.ws_connect(WS, headers=A) as ws:
        steer = Steering(ws)
        for bad in ({"command": "sideways"}, {"command": "up", "hold_ms": 10**400}, {"command": "up", "take_over": "yes"},
                    {"command": "up", "extra": 1}):
            for _ in range(http_config.motion_burst):
                reply = await steer.send(**bad)
                reply_schema.validate(reply)
                assert reply["status"] == 400 and reply["body"]["error"] == "bad_request"
        assert hub.motion.active(clock.now) is None
        assert (await steer.send(command="up"))["status"] == 200  # nothing invalid was charged


async def test_the_rate_limit_is_shared_with_post_and_stop_is_never_limited(client, hub, clock, http_config, reply_schema):
    for _ in range(http_config.motion_burst):
        assert (await client.post(MOTION, json={"command": "forward"}, headers=A)).status == 200
    async with client.ws_connect(WS, headers=A) as ws:
        steer = Steering(ws)
        refused = await steer.send(command="forward")
        reply_schema.validate(refused)
        assert refused["status"] == 429 and refused["body"]["error"] == "too_many_requests" and refused["retry_after_s"] >= 1
        assert (await steer.send(command="stop"))["status"] == 200
        assert hub.motion.active(clock.now) is None


async def test_the_lease_holds_on_the_socket_and_a_bystanders_stop_sticks(client, hub, clock, reply_schema):
    assert (await client.post(MOTION, json={"command": "forward"}, headers=A)).status == 200
    async with client.ws_connect(WS, headers=B) as ws:
        steer = Steering(ws)
        refused = await steer.send(command="turn_left")
        reply_schema.validate(refused)
        assert refused["status"] == 409 and refused["body"]["error"] == "not_in_control"
        assert refused["body"]["controller"] == "127.0.0.1/A" and refused["body"]["you"] == "127.0.0.1/B"
        assert hub.motion.active(clock.now).name == "forward"  # B's command never reached the flight loop
        assert (await steer.send(command="stop"))["status"] == 200  # stop from a bystander: applied, no lease needed
        assert hub.motion.active(clock.now) is None
        resp = await client.post(MOTION, json={"command": "forward"}, headers=A)
        assert resp.status == 409  # the stop sticks: A must take over again
        taken = await steer.send(command="turn_right", take_over=True)
        assert taken["status"] == 200 and taken["body"]["controller"] == "127.0.0.1/B"
    assert hub.motion.active(clock.now).name == "turn_right"


async def test_other_client_messages_are_ignored_and_events_still_flow(client, hub, clock):
    from feelium.events import WearerAction

    async with client.ws_connect(WS, headers=A) as ws:
        for junk in ("hello", "[1, 2]", '{"type": "ping"}', '{"command": "forward"}'):
            await ws.send_str(junk)
        steer = Steering(ws)
        assert (await steer.send(command="up"))["status"] == 200  # the junk got no reply: this is the first one
        hub.bus.publish(WearerAction("heart", clock.now, {}))
        message = json.loads((await ws.receive(timeout=5)).data)
        assert message["type"] == "wearer_action"
    assert hub.motion.active(clock.now).name == "up"


async def test_a_bad_id_is_refused_without_moving(client, hub, clock):
    async with client.ws_connect(WS, headers=A) as ws:
        await ws.send_str(json.dumps({"type": "motion", "id": "x" * 65, "command": "forward"}))
        reply = json.loads((await ws.receive(timeout=5)).data)
    assert reply["type"] == "motion_reply" and reply["status"] == 400 and reply["id"] is None
    assert hub.motion.active(clock.now) is None


async def test_a_socket_flooded_with_messages_is_closed_and_a_bystanders_stop_still_lands(aiohttp_client, hub, clock):
    """Each message costs a parse and a reply even when refused: past its budget (2 s of socket_messages_per_s at
    one instant) the socket is cut off (no close handshake to wait for), and another client's stop is applied."""
    from dataclasses import replace

    from aiohttp import WSMsgType

    from feelium.http.app import create_app, link_of
    from feelium.http.config import HttpConfig
    from tests.http.http_support import TOKEN

    config = replace(HttpConfig(), token=TOKEN, socket_messages_per_s=10.0)
    client = await aiohttp_client(create_app(config, hub, TOKEN))
    link = link_of(client.server.app)
    async with client.ws_connect(WS, headers=A) as ws:
        for i in range(50):
            await ws.send_str(json.dumps({"type": "motion", "id": i, "command": "stop"}))
        replies, ended = 0, False
        while not ended:
            msg = await ws.receive(timeout=5)
            if msg.type == WSMsgType.TEXT:
                replies += json.loads(msg.data).get("type") == "motion_reply"
            else:
                ended = msg.type in (WSMsgType.CLOSE, WSMsgType.CLOSED, WSMsgType.CLOSING, WSMsgType.ERROR)
    assert replies == 20 and link.counters["socket_floods_closed"] == 1
    assert (await client.post(MOTION, json={"command": "stop"}, headers=B)).status == 200


@pytest.mark.parametrize(
    "text",
    ['{"type": "motion", "id": 1.5, "command": "stop"}', '{"type": "motion", "id": [1], "command": "stop"}',
     '{"type": "motion", "id": 2, "command": "stop", "hold_ms": NaN}',
     '{"type": "motion", "id": 3, "command": "stop", "x": ' + "[" * 12 + "]" * 12 + "}"],
    ids=["float-id", "list-id", "nan", "nested-12"],
)
async def test_a_stop_on_the_socket_is_applied_whatever_its_id_or_formalities(client, hub, clock, text):
    async with client.ws_connect(WS, headers=A) as ws:
        steer = Steering(ws)
        assert (await steer.send(command="up"))["status"] == 200
        await ws.send_str(text)
        reply = await ws.receive_json(timeout=5)
        assert reply["type"] == "motion_reply" and reply["status"] == 200 and reply["body"]["accepted"] == "stop"
        assert hub.motion.active(clock.now) is None


async def test_a_ping_flood_counts_against_the_budget_and_pings_are_still_answered(aiohttp_client, hub):
    """Control frames cost the loop as much as data: a socket pinging past its budget is cut off like any flood,
    while a ping within it still gets its pong (the sockets answer pings themselves)."""
    from dataclasses import replace

    from aiohttp import WSMsgType

    from feelium.http.app import create_app, link_of
    from feelium.http.config import HttpConfig
    from tests.http.http_support import TOKEN

    config = replace(HttpConfig(), token=TOKEN, socket_messages_per_s=10.0)
    client = await aiohttp_client(create_app(config, hub, TOKEN))
    link = link_of(client.server.app)
    async with client.ws_connect(WS, headers=A, autoping=False) as ws:
        await ws.ping(b"hello")
        msg = await ws.receive(timeout=5)
        assert msg.type == WSMsgType.PONG and msg.data == b"hello"
        for _ in range(100):
            await ws.ping(b"x")
        ended = False
        while not ended:
            msg = await ws.receive(timeout=5)
            ended = msg.type in (WSMsgType.CLOSE, WSMsgType.CLOSED, WSMsgType.CLOSING, WSMsgType.ERROR)
    assert link.counters["socket_floods_closed"] == 1


async def test_a_stop_sent_as_a_binary_frame_is_applied(client, hub, clock):
    """A Swift client sending JSONEncoder's Data as .data(...) sends binary frames: they carry commands too."""
    async with client.ws_connect(WS, headers=A) as ws:
        steer = Steering(ws)
        assert (await steer.send(command="up"))["status"] == 200
        await ws.send_bytes(b'{"type": "motion", "id": 9, "command": "stop"}')
        reply = await ws.receive_json(timeout=5)
        assert reply["id"] == 9 and reply["status"] == 200 and hub.motion.active(clock.now) is None
