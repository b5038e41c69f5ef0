"""Motion, wearer actions, face, speech, simulated touches, state and health: thin handlers over the hub."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
from aiohttp import web

from feelium.events import SpeechIn
from feelium.wav import WavError, decode_wav, encode_wav, resample
from feelium.events import WearerAction
from feelium.http.auth import presented_token
from feelium.http.clients import client_of
from feelium.http.clock import CAPTURE_HEADER, read_clocks
from feelium.http.config import HttpConfig
from feelium.http.context import LinkContext, ctx
from feelium.http.errors import ApiError
from feelium.http.face import ImageTooLarge, JpegError, check_jpeg
from feelium.http.params import check_keys, json_object, number_field, query_number, read_body, read_json_object
from feelium.http.motion_api import apply_motion, motion_json, stop_in
from feelium.http.ratelimit import charge

ACTIONS = ("heart", "palm_raise", "palm_lower", "shimmer", "guess")
MAX_WORD = 40
MAX_CAMERA_PX = 65535.0  # bound of a simulated press coordinate (a live camera is far smaller: 409 beyond it)


async def _json_body(request: web.Request, link: LinkContext, *, required: bool = True) -> dict[str, Any]:
    return await read_json_object(request, link.config.max_json_bytes, link.config.max_json_depth, required=required)


async def post_motion(request: web.Request) -> web.Response:
    """A dead-man motion command: it lapses unless refreshed within ``hold_ms`` (rules: :func:`apply_motion`)."""
    link = ctx(request)
    client = client_of(request)
    raw = await read_body(request, link.config.max_json_bytes)
    try:
        body = json_object(raw, request, link.config.max_json_depth)
    except ApiError as exc:  # a stop sent as text/plain, with a BOM, NaN or bad bytes still stops the blimp
        stop = stop_in(raw, link.config.max_json_depth) if exc.status in (400, 415) else None
        if stop is None:
            raise
        body = stop
    return web.json_response(apply_motion(link, client, body))


async def get_motion(request: web.Request) -> web.Response:
    link = ctx(request)
    now = link.hub.clock()
    return web.json_response(motion_json(link.hub.motion.active(now), now))


async def post_action(request: web.Request) -> web.Response:
    """A wearer action (heart, palm, shimmer, guess) for the interaction engine."""
    link = ctx(request)
    name = request.match_info["action"]
    if name not in ACTIONS:
        raise ApiError(404, f"no action {name!r}; expected one of {', '.join(ACTIONS)}")
    client = client_of(request)
    body = await _json_body(request, link, required=name == "guess")
    detail: dict = {}
    if name == "guess":
        check_keys(body, {"word"})
        word = body.get("word")
        if not isinstance(word, str) or not word.strip() or len(word) > MAX_WORD:
            raise ApiError(400, f"word must be a non-empty string of at most {MAX_WORD} characters")
        detail["word"] = word.strip()
    else:
        check_keys(body, set())
    now = link.hub.clock()
    charge(link.action_limit, client, now, "wearer actions and face uploads")
    action = WearerAction(name, now, detail)  # type: ignore[arg-type]
    link.hub.bus.publish(action)
    link.count(f"action_{name}")
    return web.json_response(action.to_json(), status=202)


async def _avatar_frames(request: web.Request, limit: int, max_frames: int) -> list[bytes]:
    """The JPEG parts of a multipart avatar upload, in order; any parse failure is the client's (400)."""
    frames: list[bytes] = []
    total = 0
    try:
        reader = await request.multipart()
        while (part := await reader.next()) is not None:
            data = await part.read()  # type: ignore[union-attr]
            total += len(data)
            if total > limit:
                raise ApiError(413, f"avatar exceeds the limit of {limit} bytes")
            frames.append(bytes(data))
            if len(frames) > max_frames:
                raise ApiError(400, f"an avatar may have at most {max_frames} frames")
    except ApiError:
        raise
    except Exception as exc:  # aiohttp raises assorted types for malformed multipart input
        raise ApiError(400, f"malformed multipart body: {type(exc).__name__}: {str(exc)[:200]}") from exc
    return frames


async def put_face(request: web.Request) -> web.Response:
    """The wearer's face: one ``image/jpeg``, or a looping avatar as ``multipart/form-data`` JPEG parts."""
    link = ctx(request)
    cfg = link.config
    ctype = request.content_type
    fps = query_number(request, "fps", 12.0, 0.5, 60.0)
    if ctype not in ("image/jpeg", "multipart/form-data", "multipart/mixed"):
        raise ApiError(415, f"expected image/jpeg or multipart/form-data of JPEG frames, got {ctype}")
    client, now = client_of(request), link.hub.clock()
    if not link.action_limit.has_token(client, now):  # refused before its megabytes are read
        charge(link.action_limit, client, now, "wearer actions and face uploads")
    if link.uploads_in_flight >= cfg.max_uploads_in_flight:
        raise ApiError(429, f"{link.uploads_in_flight} face uploads are being received; retry in a second",
                       "uploads_busy", headers={"Retry-After": "1"})  # fmt: skip
    link.uploads_in_flight += 1
    try:
        frames = await _face_frames(request, ctype, cfg)
    finally:
        link.uploads_in_flight -= 1
    try:
        for i, frame in enumerate(frames):
            check_jpeg(frame, cfg.max_face_pixels, "body" if len(frames) == 1 else f"frame {i}")
    except ImageTooLarge as exc:
        raise ApiError(413, str(exc), "image_too_large") from exc
    except JpegError as exc:
        raise ApiError(400, str(exc)) from exc
    charge(link.action_limit, client, link.hub.clock(), "wearer actions and face uploads")
    link.face.show(frames, fps)
    return web.json_response({"frames": len(frames), "fps": fps if len(frames) > 1 else None, "bytes": sum(map(len, frames))})


async def _face_frames(request: web.Request, ctype: str, cfg: HttpConfig) -> list[bytes]:
    """The JPEG frames of a face upload, read within the size limits."""
    if ctype == "image/jpeg":
        return [await read_body(request, cfg.max_face_bytes)]
    if request.content_length is not None and request.content_length > cfg.max_face_bytes:
        raise ApiError(413, f"avatar of {request.content_length} bytes exceeds the limit of {cfg.max_face_bytes} bytes")
    frames = await _avatar_frames(request, cfg.max_face_bytes, cfg.max_avatar_frames)
    if not frames:
        raise ApiError(400, "the avatar has no frames")
    return frames


async def delete_face(request: web.Request) -> web.Response:
    """Clear the wearer's face: the projector shows its default avatar again."""
    link = ctx(request)
    charge(link.action_limit, client_of(request), link.hub.clock(), "wearer actions and face uploads")
    link.face.clear()
    return web.json_response({"cleared": True})


async def post_speech(request: web.Request) -> web.Response:
    """One chunk of the wearer's speech as a PCM16 WAV, queued for the speaker (backlog bounded by [audio] max_playback_ms)."""
    link = ctx(request)
    if request.content_type not in ("audio/wav", "audio/x-wav", "audio/wave", "application/octet-stream"):
        raise ApiError(415, f"expected audio/wav (PCM16), got {request.content_type}")
    data = await read_body(request, link.config.max_speech_bytes)
    try:
        samples, rate = decode_wav(data)
    except WavError as exc:
        raise ApiError(400, str(exc)) from exc
    charge(link.speech_limit, client_of(request), link.hub.clock(), "speech chunks")
    target = link.speech_settings.sample_rate
    pcm = resample(samples, rate, target).astype("<i2").tobytes()
    link.hub.bus.publish(SpeechIn(pcm, target, link.hub.clock()))
    link.count("speech_chunks_in")
    return web.json_response(
        {"samples": len(pcm) // 2, "rate": target, "ms": round(1000.0 * len(pcm) / (2 * target), 1)}, status=202
    )


async def get_speech(request: web.Request) -> web.StreamResponse:
    """Room audio captured after ``?after=SEQ`` as one WAV; 204 when none came within ``timeout``."""
    link = ctx(request)
    after = int(query_number(request, "after", 0, 0, 2**53, integer=True))
    timeout = query_number(request, "timeout", 0.0, 0.0, 5.0)
    chunks, last = await link.speech.wait_after(after, timeout)
    headers = {"X-Speech-Seq": str(last), "Cache-Control": "no-store"}
    if not chunks:
        return web.Response(status=204, headers=headers)
    headers[CAPTURE_HEADER] = f"{chunks[-1].t:.6f}"  # when the WAV's last sample was captured, daemon clock
    rate = chunks[-1].rate
    pcm = b"".join(c.pcm for c in chunks if c.rate == rate)
    link.count("speech_chunks_out", len(chunks))
    return web.Response(body=encode_wav(pcm, rate), content_type="audio/wav", headers=headers)


def scene_size(scene: object) -> tuple[int | None, int | None]:
    """The rear camera's size from the live scene (or the scene a thread-safe wrapper holds)."""
    for obj in (scene, getattr(scene, "scene", None)):
        width, height = getattr(obj, "width", None), getattr(obj, "height", None)
        if isinstance(width, int) and isinstance(height, int):
            return width, height
    return None, None


def _scene(request: web.Request):  # type: ignore[no-untyped-def]
    scene = ctx(request).hub.rear_scene
    if scene is None:
        raise ApiError(404, "simulated touches need the daemon in sim mode (no live rear scene here)", "not_sim")
    return scene


async def post_sim_press(request: web.Request) -> web.Response:
    """Press (or hover) a simulated fingertip on the rear camera at ``x``, ``y`` (camera pixels)."""
    link = ctx(request)
    scene = _scene(request)
    body = await _json_body(request, link)
    check_keys(body, {"x", "y", "hover"})
    size = scene_size(scene)
    width, height = float(size[0] or 10000), float(size[1] or 10000)
    if "x" not in body or "y" not in body:
        raise ApiError(400, "x and y (camera pixels) are required")
    x = number_field(body, "x", None, 0.0, MAX_CAMERA_PX)
    y = number_field(body, "y", None, 0.0, MAX_CAMERA_PX)
    if x is None or y is None:
        raise ApiError(400, "x and y must be numbers")
    if x > width - 1 or y > height - 1:  # valid numbers, but the live camera is smaller
        raise ApiError(409, f"({x:g}, {y:g}) is outside the {width:g}x{height:g} rear camera", "outside_frame")
    hover = body.get("hover", False)
    if not isinstance(hover, bool):
        raise ApiError(400, "hover must be true or false")
    try:
        scene.press(x, y, link.hub.clock(), hover=hover)
    except ValueError as exc:
        raise ApiError(409, f"the simulator refused the press: {exc}") from exc
    link.count("sim_presses")
    return web.json_response({"x": x, "y": y, "hover": hover}, status=202)


async def post_sim_release(request: web.Request) -> web.Response:
    """Lift the simulated fingertip."""
    link = ctx(request)
    scene = _scene(request)
    body = await _json_body(request, link, required=False)
    check_keys(body, set())
    try:
        scene.release(link.hub.clock())
    except ValueError as exc:
        raise ApiError(409, f"the simulator refused the release: {exc}") from exc
    return web.json_response({"released": True}, status=202)


async def get_sim(request: web.Request) -> web.Response:
    """Whether simulated touches are available, and the rear camera's size."""
    scene = ctx(request).hub.rear_scene
    if scene is None:
        return web.json_response({"sim": False})
    width, height = scene_size(scene)
    return web.json_response({"sim": True, "width": width, "height": height})


async def get_state(request: web.Request) -> web.Response:
    """Everything the services report (touch, presence, altitude, battery...) plus the link and motion."""
    link = ctx(request)
    now = link.hub.clock()
    state = link.hub.state.snapshot()
    body = {
        "t": round(now, 4),
        "services": state,
        "motion_command": motion_json(link.hub.motion.active(now), now),
        "headset_link": link.link_state(now),
        "last_seq": link.events.ring.last_seq,
        "epoch": link.events.ring.epoch,
    }
    return web.json_response(body, dumps=_dumps)


async def get_clock(request: web.Request) -> web.Response:
    """The daemon clock every API time is on, read together with the wall clock (``wall = t + offset_s``)."""
    link = ctx(request)
    return web.json_response(read_clocks(link.hub.clock, link.wall_clock).to_json(), headers={"Cache-Control": "no-store"})


async def get_health(request: web.Request) -> web.Response:
    """``{"status": "alive"}`` for anyone (monitors); the supervisor's per-service report only with the token,
    since it tells a stranger whether someone is near the blimp and who is wearing the headset."""
    link = ctx(request)
    if not link.tokens.matches(presented_token(request.headers, request.query, request.cookies), link.hub.clock()):
        return web.json_response({"status": "alive"})
    try:
        report = dict(link.hub.health())
    except Exception as exc:  # the supervisor's report must never take the endpoint down
        report = {"status": "degraded", "error": f"{type(exc).__name__}: {exc}"}
    report.setdefault("status", "ok")
    return web.json_response(report, dumps=_dumps)


def _dumps(obj: object) -> str:
    """JSON of service reports, which may hold numpy scalars or non-finite floats (sent as null)."""

    def clean(value: object) -> object:
        if isinstance(value, dict):
            return {str(k): clean(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [clean(v) for v in value]
        if isinstance(value, np.generic):
            value = value.item()
        if isinstance(value, float) and not math.isfinite(value):
            return None
        if value is None or isinstance(value, (str, int, float, bool)):
            return value
        return str(value)

    return json.dumps(clean(obj))
