"""Motion commands under the headset link's rules, whichever transport carries them.

``POST /motion`` and a ``{"type": "motion"}`` message on the events WebSocket
(``GET /events/ws``) go through :func:`apply_motion`, so both obey the same
rules in the same order: the body is validated first; a ``stop`` is then
applied at once from any client (never rate limited, never refused for want
of the lease, and it hands its sender the lease); any other command is charged
to the client's bucket and needs the lease (``take_over`` to take it).

Why a second transport: a headset refreshing the dead man at 20 Hz over HTTP
pays a whole request each time (parsing, authentication, routing, a response),
~20 requests a second on the blimp's one event-loop thread. Over the WebSocket it
already holds for events, each refresh is one small text message and one reply.
"""

from __future__ import annotations

import json
from typing import Any

from feelium.http.context import LinkContext
from feelium.http.errors import ApiError
from feelium.http.params import check_keys, json_depth, number_field, parse_json
from feelium.http.ratelimit import charge
from feelium.motion import DEFAULT_HOLD_S, MOTION_NAMES, NEUTRAL_NAMES

MOTION_FIELDS = {"command", "hold_ms", "take_over"}
MAX_ID_CHARS = 64
MAX_ID = 2**53


def motion_json(cmd: Any, now: float) -> dict[str, Any]:
    """The command in force as the API shows it (``MotionState``)."""
    if cmd is None:
        return {"command": "stop", "active": False, "remaining_ms": 0, "source": None}
    return {
        "command": cmd.name,
        "active": True,
        "remaining_ms": round(1000.0 * max(0.0, cmd.expires_at - now), 1),
        "source": cmd.source,
    }


def apply_motion(link: LinkContext, client: str, body: dict[str, Any]) -> dict[str, Any]:
    """Validate ``body`` (``MotionRequest``), apply it for ``client``; the ``MotionState`` answer, or ApiError
    (400 invalid, 429 rate limited, 409 ``not_in_control``).

    A ``stop`` wins over everything else its body holds: it is applied whatever other fields come with it
    (unknown or invalid ones are named in ``ignored``), since refusing a stop for a formality would leave
    the blimp moving."""
    if body.get("command") in NEUTRAL_NAMES:
        return _stop(link, client, body)
    check_keys(body, MOTION_FIELDS)
    name = body.get("command")
    if not isinstance(name, str) or name not in MOTION_NAMES:
        raise ApiError(400, f"command must be one of {', '.join(MOTION_NAMES)}, got {str(name)[:40]!r}")
    max_ms = 1000.0 * link.hub.motion.max_hold_s
    hold_ms = number_field(body, "hold_ms", 1000.0 * DEFAULT_HOLD_S, 1.0, max_ms)
    assert hold_ms is not None
    take_over = body.get("take_over", False)
    if not isinstance(take_over, bool):
        raise ApiError(400, "take_over must be true or false")
    now = link.hub.clock()
    charge(link.motion_limit, client, now, "motion commands")
    holder = link.lease.claim(client, now, take_over)
    if holder is not None:
        raise ApiError(
            409,
            f"{holder.client} is steering; send the command with \"take_over\": true to take control, "
            f"or wait until its lease lapses ({link.lease.lease_s:g} s after its last motion command)",
            "not_in_control",
            extra={"controller": holder.client, "lease_remaining_s": round(holder.expires_at - now, 3), "you": client},
        )
    cmd = link.hub.motion.command(name, now, hold_ms / 1000.0, source="headset")
    link.last_motion_at = now
    return motion_json(link.hub.motion.active(now), now) | {"accepted": cmd.name, "controller": client}


def _stop(link: LinkContext, client: str, body: dict[str, Any]) -> dict[str, Any]:
    """Apply a stop at once for any client (no bucket, no lease; it hands its sender the lease)."""
    now = link.hub.clock()
    cmd = link.hub.motion.command("stop", now, source="headset")
    link.lease.stopped_by(client, now)
    link.count("motion_stops")
    link.last_motion_at = now
    answer = motion_json(link.hub.motion.active(now), now) | {"accepted": cmd.name, "controller": client}
    ignored = sorted(k for k in body if k not in MOTION_FIELDS or not _valid_for_stop(k, body[k], link))
    return answer | ({"ignored": ignored} if ignored else {})


def _valid_for_stop(key: str, value: Any, link: LinkContext) -> bool:
    """Whether a stop's other field is one ``POST /motion`` accepts (a stop ignores it either way)."""
    if key == "command":
        return True
    if key == "take_over":
        return isinstance(value, bool)
    try:
        number_field({key: value}, key, None, 1.0, 1000.0 * link.hub.motion.max_hold_s)
    except ApiError:
        return False
    return True


# Nesting a lenient reading still accepts: Python's json recurses once per level, so the strict limit's reason
# (no RecursionError) holds here too, only further out.
LENIENT_MAX_DEPTH = 64


def _lenient_int(digits: str) -> int | None:
    """An integer too long for Python's digit limit is no reason to refuse the stop it rides with."""
    return int(digits) if len(digits) <= 100 else None


def stop_in(raw: bytes, max_depth: int) -> dict[str, Any] | None:
    """The body, when ``raw`` holds a JSON object whose ``command`` is a stop, read leniently: whatever its
    declared content type, a UTF-8 BOM, bytes that are not UTF-8 in other fields, ``NaN``, data after the
    object, nesting up to ``LENIENT_MAX_DEPTH``. Strict rules would refuse such a stop for a formality."""
    try:
        value = parse_json(raw, max_depth)
    except ApiError:
        text = raw.decode("utf-8", errors="replace").lstrip("\ufeff \t\r\n")
        if json_depth(text) > LENIENT_MAX_DEPTH:
            return None
        try:
            decoder = json.JSONDecoder(parse_constant=lambda _: None, parse_int=_lenient_int)
            value, _ = decoder.raw_decode(text)
        except ValueError:
            return None
    return value if isinstance(value, dict) and value.get("command") in NEUTRAL_NAMES else None


def motion_message(link: LinkContext, client: str, text: str) -> dict[str, Any] | None:
    """The ``MotionReply`` to one text message a client sent on the events WebSocket, ``None`` when the
    message is no motion command (ignored, as every client message was before motion could ride along).

    ``{"type": "motion", "id": 17, "command": ..., "hold_ms": ..., "take_over": ...}``: the fields after
    ``type`` and ``id`` are ``POST /motion``'s body under its rules; the reply carries the status and body
    that request would have got, and the client's ``id`` to match them up. A 429 adds ``retry_after_s``
    (the request's ``Retry-After`` header).
    """
    raw = text.encode("utf-8", errors="surrogateescape")
    try:
        value = parse_json(raw, link.config.max_json_depth)
    except ApiError:
        value = stop_in(raw, link.config.max_json_depth)  # a malformed stop still stops
    if not isinstance(value, dict) or value.get("type") != "motion":
        return None
    link.last_request_at = link.hub.clock()
    link.count("motion_socket_messages")
    body = {k: v for k, v in value.items() if k not in ("type", "id")}
    ref = value.get("id")
    if ref is not None and not _valid_id(ref):
        if body.get("command") in NEUTRAL_NAMES:  # a stop is applied whatever its id; the reply cannot carry it
            return {"type": "motion_reply", "id": None, "status": 200, "body": apply_motion(link, client, body | {"id": ref})}
        return _reply(None, ApiError(400, f"id must be an integer 0..2^53 or a string of at most {MAX_ID_CHARS} characters"))
    try:
        return {"type": "motion_reply", "id": ref, "status": 200, "body": apply_motion(link, client, body)}
    except ApiError as exc:
        return _reply(ref, exc)


def _valid_id(ref: Any) -> bool:
    if isinstance(ref, bool):
        return False
    return (isinstance(ref, int) and 0 <= ref <= MAX_ID) or (isinstance(ref, str) and len(ref) <= MAX_ID_CHARS)


def _reply(ref: Any, error: ApiError) -> dict[str, Any]:
    """A refused command's reply: the status and error body ``POST /motion`` would have answered."""
    reply = {"type": "motion_reply", "id": ref, "status": error.status,
             "body": {"error": error.code, "message": error.message} | error.extra}
    if "Retry-After" in error.headers:
        reply["retry_after_s"] = int(error.headers["Retry-After"])
    return reply
