"""The headset API application: routes, middlewares and the background pumps, built from config and a hub."""

from __future__ import annotations

import asyncio
import contextlib
import secrets
import socket
from pathlib import Path

from aiohttp import web

from feelium.http import control, events_api, lens_api, pairing_api, speech_api, video
from feelium.http.auth import TokenStore
from feelium.http.config import MIN_TOKEN_CHARS, HttpConfig
from feelium.http.context import CONTEXT, LinkContext, SpeechSettings, ctx
from feelium.http.errors import ERROR_STATS, ApiError, json_errors
from feelium.http.face import FacePlayer
from feelium.http.feed import EventFeed
from feelium.http.jpeg import JpegFeed
from feelium.http.openapi import openapi_document
from feelium.http.pairing import PairingCodes
from feelium.http.lease import ControlLease
from feelium.http.ratelimit import ClientBuckets
from feelium.http.open_streams import CHECK_EVERY_S, OpenStreams
from feelium.http.slots import StreamSlots
from feelium.http.hosts import HostAllowList
from feelium.http.security import (
    API_PREFIX, add_cors_headers, make_cors_middleware, make_host_middleware, parse_origins, require_token,
)
from feelium.http.speech import SpeechFeed
from feelium.hub import Hub

STATIC_DIR = Path(__file__).with_name("static")
_PUMPS: web.AppKey[list[asyncio.Task[None]]] = web.AppKey("feelium_pumps", list)


def build_context(config: HttpConfig, hub: Hub, token: str, speech: SpeechSettings | None = None) -> LinkContext:
    speech = speech or SpeechSettings()
    videos = {
        "front": JpegFeed("front", hub.front_video, config.jpeg_quality),
        "rear": JpegFeed("rear", hub.rear_video, config.jpeg_quality),
        "projector": JpegFeed("projector", hub.projector_video, config.jpeg_quality),
    }
    return LinkContext(
        config=config,
        speech_settings=speech,
        hub=hub,
        tokens=TokenStore(token, None if config.token else config.token_file),
        pairing=PairingCodes(config.pairing_ttl_s),
        events=EventFeed(hub.bus, config.event_ring_size, secrets.token_hex(4)),  # a new epoch per run
        speech=SpeechFeed(hub.bus, speech.capture_keep_ms),
        videos=videos,
        face=FacePlayer(hub),
        motion_limit=ClientBuckets(config.motion_rate_per_s, config.motion_burst, clients_per_address=config.clients_per_address),
        action_limit=ClientBuckets(config.action_rate_per_s, config.action_burst, clients_per_address=config.clients_per_address),
        speech_limit=ClientBuckets(config.speech_rate_per_s, config.speech_burst, clients_per_address=config.clients_per_address),
        lease=ControlLease(config.control_lease_s),
        streams=StreamSlots(config.max_stream_clients, config.max_streams_per_client, per_address=config.max_streams_per_address),
        speech_streams=StreamSlots(config.max_speech_streams, config.max_speech_streams_per_client, "speech streams",
                                   per_address=config.max_speech_streams_per_address),
        event_streams=StreamSlots(config.max_event_streams, config.max_event_streams_per_client, "event streams",
                                  per_address=config.max_event_streams_per_address),
        open_streams=OpenStreams(),
    )


async def _start_pumps(app: web.Application) -> None:
    link = app[CONTEXT]
    link.events.start()  # subscribe now, so nothing published after startup is missed
    link.speech.start()
    app[_PUMPS] = [asyncio.create_task(link.events.pump()), asyncio.create_task(_close_revoked_streams(link))]


async def _close_revoked_streams(link: LinkContext) -> None:
    """Each second, end the streams opened with a token that no longer matches (rotated away)."""
    while True:
        await asyncio.sleep(CHECK_EVERY_S)
        now = link.hub.clock()
        link.open_streams.close_revoked(lambda token: link.tokens.matches(token, now))


async def _stop_pumps(app: web.Application) -> None:
    link = app[CONTEXT]
    for task in app.get(_PUMPS, []):
        task.cancel()
    for task in app.get(_PUMPS, []):
        with contextlib.suppress(asyncio.CancelledError):
            await task
    link.events.close()
    link.speech.close()
    await link.face.close()


async def openapi(request: web.Request) -> web.Response:
    return web.json_response(openapi_document())


async def index(request: web.Request) -> web.FileResponse:
    return web.FileResponse(STATIC_DIR / "index.html", headers={"Cache-Control": "no-cache"})


async def partner(request: web.Request) -> web.FileResponse:
    return web.FileResponse(STATIC_DIR / "partner.html", headers={"Cache-Control": "no-cache"})


async def static_file(request: web.Request) -> web.FileResponse:
    """A file of the browser client; a missing one is a JSON 404 (aiohttp's static route answers an empty body)."""
    name = request.match_info["name"]
    path = STATIC_DIR / name
    if "/" in name or "\\" in name or name.startswith(".") or not path.is_file():
        raise ApiError(404, f"no such file: /static/{name[:80]}")
    return web.FileResponse(path)


def create_app(config: HttpConfig, hub: Hub, token: str, speech: SpeechSettings | None = None) -> web.Application:
    """The aiohttp application of the headset link (the caller runs it)."""
    if len(token) < MIN_TOKEN_CHARS:
        raise ValueError(f"the API token must be at least {MIN_TOKEN_CHARS} characters")
    link = build_context(config, hub, token, speech)
    limit = max(config.max_json_bytes, config.max_face_bytes, config.max_speech_bytes) + 65536
    app = web.Application(
        client_max_size=limit,
        middlewares=[
            json_errors,
            make_host_middleware(HostAllowList.from_config(config.allowed_hosts, socket.gethostname())),
            make_cors_middleware(parse_origins(config.cors_origins)),
            require_token,
        ],
    )
    app[CONTEXT] = link
    app[ERROR_STATS] = link.counters
    app.on_startup.append(_start_pumps)
    app.on_shutdown.append(_stop_pumps)
    app.on_response_prepare.append(add_cors_headers)
    p = API_PREFIX
    app.router.add_get(f"{p}/openapi.json", openapi)
    app.router.add_get(f"{p}/health", control.get_health)
    app.router.add_get(f"{p}/clock", control.get_clock)
    app.router.add_post(f"{p}/pair", pairing_api.post_pair)
    app.router.add_post(f"{p}/pair/code", pairing_api.post_pair_code)
    app.router.add_post(f"{p}/token/rotate", pairing_api.post_token_rotate)
    app.router.add_post(f"{p}/session", pairing_api.post_session)
    app.router.add_get(f"{p}/state", control.get_state)
    app.router.add_get(f"{p}/lens", lens_api.get_lens)
    app.router.add_get(f"{p}/video/{{camera}}.mjpeg", video.mjpeg)
    app.router.add_get(f"{p}/video/{{camera}}.jpg", video.jpeg)
    app.router.add_post(f"{p}/motion", control.post_motion)
    app.router.add_get(f"{p}/motion", control.get_motion)
    app.router.add_get(f"{p}/events", events_api.long_poll)
    app.router.add_get(f"{p}/events/stream", events_api.sse)
    app.router.add_get(f"{p}/events/ws", events_api.websocket)
    app.router.add_put(f"{p}/face", control.put_face)
    app.router.add_delete(f"{p}/face", control.delete_face)
    app.router.add_post(f"{p}/speech", control.post_speech)
    app.router.add_get(f"{p}/speech", control.get_speech)
    app.router.add_get(f"{p}/speech/stream", speech_api.stream)
    app.router.add_post(f"{p}/actions/{{action}}", control.post_action)
    app.router.add_get(f"{p}/sim", control.get_sim)
    app.router.add_post(f"{p}/sim/press", control.post_sim_press)
    app.router.add_post(f"{p}/sim/release", control.post_sim_release)
    app.router.add_get("/", index)
    app.router.add_get("/partner", partner)
    app.router.add_get("/static/{name}", static_file)
    return app


def link_of(app: web.Application) -> LinkContext:
    """The shared state of a built app (tests and the service read counters from it)."""
    return app[CONTEXT]


__all__ = ["SpeechSettings", "create_app", "link_of", "ctx"]
