"""The OpenAPI 3.1 description of the headset API (served at ``/api/v1/openapi.json``).

Written by hand next to the handlers so a visionOS developer gets one exact
contract; ``tests/http`` validates it and runs schemathesis against a live
server to keep the two in step.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from feelium.http.clients import CLIENT_HEADER, CLIENT_ID_PATTERN
from feelium.http.control import MAX_CAMERA_PX, MAX_WORD
from feelium.http.events_api import MAX_SEQ
from feelium.http.lens_api import LENS_SCHEMA, openapi_paths as lens_paths
from feelium.http.openapi_messages import error_schema, event_stream_extensions, message_schemas, speech_stream_path
from feelium.http.video import MAX_FPS, MIN_FPS
from feelium.motion import MAX_HOLD_S, MOTION_NAMES

CAPTURE_T = {"description": "When it was captured (the last sample, for speech): daemon clock, s; see /clock.", "schema": {"type": "number"}}
RESUME_PATTERN = "^([^:]{1,32}:)?[0-9]{1,15}$"  # 15 digits stay below 2**53
SKIN_UV = (
    "Skin coordinates u, v (touch events): 0..1 across the membrane's sensitive patch, origin at its top-left "
    "corner as seen from inside the blimp looking forward (the front camera's and the wearer's direction), u "
    "right, v down (a partner facing the blimp sees u grow to their left); 0 and 1 are the patch's outer edges. "
    "x, y are rear-camera pixels; neither is a front-camera pixel (GET /lens describes the front camera)."
)
ACTIONS = ("heart", "palm_raise", "palm_lower", "shimmer", "guess")


def _ref(name: str) -> dict[str, str]:
    return {"$ref": f"#/components/schemas/{name}"}


def _json(schema: dict[str, Any], description: str) -> dict[str, Any]:
    return {"description": description, "content": {"application/json": {"schema": schema}}}


def _errors(*codes: int) -> dict[str, Any]:
    text = {
        400: "The request is malformed; the message says which field.",
        401: "Missing or wrong token.",
        403: "The Host is not one of the blimp's names, the Origin is not allowed, or (pairing) the code is wrong, used or expired.",
        404: "Not found (or not available in this mode).",
        409: "The simulator refused the request.",
        413: "The body exceeds the configured limit.",
        415: "Wrong Content-Type (JSON bodies must be application/json, UTF-8).",
        429: "This client's rate limit or a stream limit reached; see Retry-After.",
    }
    # a browser page from a foreign origin is refused on every endpoint, before the token is looked at
    return {str(c): _json(_ref("Error"), text[c]) for c in sorted({*codes, 403})}


def _query(name: str, schema: dict[str, Any], description: str) -> dict[str, Any]:
    return {"name": name, "in": "query", "required": False, "schema": schema, "description": description}


TOKEN_QUERY = _query("token", {"type": "string"}, "The token, for clients that can neither set headers nor hold the /session cookie.")
_CLIENT_ID = {"type": "string", "pattern": CLIENT_ID_PATTERN}
CLIENT_ID_HEADER = {
    "name": CLIENT_HEADER, "in": "header", "required": False, "schema": _CLIENT_ID,
    "description": "The client's own id (e.g. a UUID made at app launch). With the remote address it is the "
    "client identity of rate limits, stream slots and the motion lease; without it the address alone is. "
    "A value outside the pattern is ignored.",
}  # fmt: skip
CLIENT_ID_QUERY = _query("client", _CLIENT_ID, f"The {CLIENT_HEADER} id, for clients that cannot set headers.")


def _add_stream_messages(paths: dict[str, Any]) -> None:
    """The streamed messages' schemas on the event operations, and the speech stream (``openapi_messages.py``)."""
    by_id = {op["operationId"]: op for item in paths.values() for op in item.values()}
    for operation_id, extension in event_stream_extensions().items():
        by_id[operation_id].update(extension)
    paths["/speech/stream"] = speech_stream_path(_errors(400, 401, 429), [TOKEN_QUERY, CLIENT_ID_HEADER, CLIENT_ID_QUERY])


@lru_cache(maxsize=1)
def openapi_document() -> dict[str, Any]:
    """The whole document (built once)."""
    motion_state = {
        "type": "object",
        "required": ["command", "active", "remaining_ms"],
        "properties": {
            "command": {"type": "string", "enum": list(MOTION_NAMES)},
            "active": {"type": "boolean"},
            "remaining_ms": {"type": "number", "minimum": 0},
            "source": {"type": ["string", "null"]},
            "accepted": {"type": "string", "enum": list(MOTION_NAMES)},
            "controller": {"type": "string", "description": "The client identity now holding the motion lease (POST only)."},
            "ignored": {
                "type": "array", "items": {"type": "string"},
                "description": "A stop's other fields that were unknown or invalid: the stop was applied anyway.",
            },
        },
    }
    schemas: dict[str, Any] = {
        "Error": error_schema(),
        "EventBatch": {
            "type": "object",
            "required": ["events", "last_seq", "epoch", "resume", "reset"],
            "properties": {
                "events": {"type": "array", "items": _ref("Event")},
                "last_seq": {"type": "integer", "minimum": 0},
                "epoch": {"type": "string"},
                "resume": {"type": "string", "description": "EPOCH:SEQ: the next `after`."},
                "reset": {"type": "boolean", "description": "Events were lost or the daemon restarted: `state` (included) "
                          "replaces them, `events` is empty; continue from `resume`."},
                "state": _ref("ServicesState"),
            },
        },
        "MotionRequest": {
            "type": "object",
            "required": ["command"],
            "additionalProperties": False,
            "properties": {
                "command": {"type": "string", "enum": list(MOTION_NAMES)},
                "hold_ms": {
                    "type": "number", "minimum": 1, "maximum": 1000 * MAX_HOLD_S, "default": 500,
                    "description": "Dead man: the command lapses unless refreshed within this time.",
                },
                "take_over": {
                    "type": "boolean", "default": False,
                    "description": "Take the motion lease from the client that holds it (else 409 not_in_control). "
                    "Not needed for stop, which every client may send at any time.",
                },
            },
        },  # fmt: skip
        "NotInControl": {
            "type": "object",
            "required": ["error", "message", "controller", "lease_remaining_s", "you"],
            "properties": {
                "error": {"const": "not_in_control"},
                "message": {"type": "string"},
                "controller": {"type": "string", "description": "The client identity that holds the lease."},
                "lease_remaining_s": {"type": "number", "minimum": 0, "description": "When it lapses unless that client moves again."},
                "you": {"type": "string", "description": "Your own client identity as the server sees it."},
            },
        },  # fmt: skip
        "MotionState": motion_state,
        "State": {
            "type": "object",
            "required": ["t", "services", "motion_command", "headset_link", "last_seq"],
            "properties": {
                "t": {"type": "number"},
                "services": _ref("ServicesState"),
                "motion_command": motion_state,
                "headset_link": {
                    "type": "object",
                    "properties": {"controller": {"type": ["string", "null"], "description": "Who holds the motion lease."}},
                },
                "last_seq": {"type": "integer"},
                "epoch": {"type": "string", "description": "Resume events after `epoch:last_seq`."},
            },
        },
        "Health": {
            "type": "object", "required": ["status"], "properties": {"status": {"type": "string"}},
            "description": "Without the token only {\"status\": \"alive\"}; with it the supervisor's report (status ok, degraded...; services).",
        },
        "WearerAction": {
            "type": "object",
            "required": ["action", "t"],
            "properties": {"action": {"type": "string", "enum": list(ACTIONS)}, "t": {"type": ["number", "null"]}},
        },
        "SimPress": {
            "type": "object",
            "required": ["x", "y"],
            "additionalProperties": False,
            "properties": {
                "x": {"type": "number", "minimum": 0, "maximum": MAX_CAMERA_PX, "description": "Rear camera pixels (409 outside the live camera)."},
                "y": {"type": "number", "minimum": 0, "maximum": MAX_CAMERA_PX},
                "hover": {"type": "boolean", "default": False, "description": "Hover above instead of pressing."},
            },
        },
    }
    schemas |= message_schemas()
    json_body = lambda schema, required=True: {  # noqa: E731
        "required": required,
        "content": {"application/json": {"schema": schema}},
    }
    cameras = {"name": "camera", "in": "path", "required": True, "schema": {"type": "string", "enum": ["front", "rear", "projector"]}}
    resume = {"type": "string", "pattern": RESUME_PATTERN, "maxLength": 60}
    after = _query("after", resume, "Resume token EPOCH:SEQ of the last event seen (a bare SEQ is taken as this run's); "
                   "omitted = only new events; another run's epoch = reset.")
    paths: dict[str, Any] = {
        "/health": {"get": {
            "operationId": "health", "summary": "Alive for anyone; the per-service health with the token.", "security": [],
            "responses": {"200": _json(_ref("Health"), "The supervisor's report.")} | _errors(),
        }},
        "/clock": {"get": {
            "operationId": "clock",
            "summary": "The daemon clock every API time is on (event and state `t`, X-Feelium-Capture-T), read together with the wall clock.",
            "description": "Unix time of a daemon time t = t + offset_s. The daemon clock is monotonic seconds since an "
            "arbitrary start; it never jumps. uncertainty_s bounds how far apart the two reads were.",
            "responses": {"200": _json({
                "type": "object", "required": ["t", "wall", "offset_s", "uncertainty_s"],
                "properties": {k: {"type": "number"} for k in ("t", "wall", "offset_s", "uncertainty_s")},
            }, "The two clocks now.")} | _errors(401),
        }},
        "/pair/code": {"post": {
            "operationId": "pairingCode", "summary": "A new pairing code (what `feelium pair` prints); replaces the outstanding one.",
            "responses": {"200": _json({
                "type": "object", "required": ["code", "expires_in_s"],
                "properties": {"code": {"type": "string", "examples": ["4821-0937"]}, "expires_in_s": {"type": "number"}},
            }, "The code; it works once, for expires_in_s ([http] pairing_ttl_s).")} | _errors(401),
        }},
        "/pair": {"post": {
            "operationId": "pair", "security": [],
            "summary": "Exchange a pairing code for the token (no token needed). A code works once and expires; "
            "after 5 wrong codes the outstanding one is void.",
            "parameters": [CLIENT_ID_HEADER],
            "requestBody": json_body({
                "type": "object", "required": ["code"], "additionalProperties": False,
                "properties": {"code": {"type": "string", "minLength": 1, "maxLength": 32, "description": "As printed; dashes and spaces are ignored."}},
            }),
            "responses": {"200": _json({"type": "object", "required": ["token"], "properties": {"token": {"type": "string"}}}, "The bearer token.")}
            | _errors(400, 413, 415, 429),
        }},
        "/session": {"post": {
            "operationId": "session",
            "summary": "Set the token as an HttpOnly, SameSite=Strict cookie (path /api/v1) so a browser page's img, "
            "EventSource and WebSocket need no ?token=. Native clients do not need it.",
            "responses": {"204": {"description": "Cookie set (Set-Cookie: feelium_token=...)."}} | _errors(401),
        }},
        "/token/rotate": {"post": {
            "operationId": "rotateToken",
            "summary": "Replace the token (in force at once; the one that authorised this request stops working).",
            "description": "409 token_not_rotatable when the token is set in [http] token rather than token_file.",
            "responses": {"200": _json({"type": "object", "required": ["token"], "properties": {"token": {"type": "string"}}}, "The new token."),
                          "409": _json(_ref("Error"), "The token comes from the config file.")} | _errors(401),
        }},
        "/state": {"get": {
            "operationId": "state", "summary": "Live state as the services provide it.",
            "responses": {"200": _json(_ref("State"), "State.")} | _errors(401),
        }},
        "/video/{camera}.jpg": {"get": {
            "operationId": "videoJpeg", "summary": "The newest frame as a JPEG.", "parameters": [cameras, TOKEN_QUERY],
            "responses": {
                "200": {"description": "JPEG.", "headers": {"X-Feelium-Capture-T": CAPTURE_T, "X-Frame-Seq": {"schema": {"type": "integer"}}},
                        "content": {"image/jpeg": {"schema": {"type": "string", "contentMediaType": "image/jpeg"}}}},
            } | _errors(401, 404),
        }},
        "/video/{camera}.mjpeg": {"get": {
            "operationId": "videoMjpeg",
            "summary": "MJPEG stream (multipart/x-mixed-replace; boundary=feeliumframe), newest frame always.",
            "description": "Each stream takes a slot: at most `max_streams_per_client` per client and `max_stream_clients` "
            "in all (429 above). A client whose socket accepts nothing for `stream_write_timeout_s` is dropped "
            "and its slot freed.",
            "parameters": [
                cameras, TOKEN_QUERY, CLIENT_ID_HEADER, CLIENT_ID_QUERY,
                _query("fps", {"anyOf": [{"const": 0}, {"type": "number", "minimum": MIN_FPS, "maximum": MAX_FPS}]},
                       f"Rate cap; 0 = camera rate; 0 < fps < {MIN_FPS:g} is 400 (a stream must write often enough "
                       "for the write timeout to notice a client that stopped reading)."),
            ],
            "x-streaming": True,
            "responses": {
                "200": {"description": "Endless stream of JPEG parts; each part's headers carry Content-Length, "
                        "X-Feelium-Capture-T (capture time, daemon clock, s) and X-Frame-Seq.", "content": {"multipart/x-mixed-replace": {"schema": {"type": "string"}}}},
            } | _errors(400, 401, 404, 429),
        }},
        "/motion": {
            "post": {
                "operationId": "motion", "summary": "Dead-man motion command (refresh within hold_ms or the blimp stops).",
                "description": "stop is applied at once from any client: never rate limited, never refused for want "
                "of control, and it hands the sender the motion lease. Other commands are charged to the client's "
                "rate limit (after validation) and need the lease: the first client to move holds it, each of its "
                "motion commands renews it, and it lapses after `control_lease_s` without one. Another client "
                "gets 409 not_in_control until it sends `take_over: true`.",
                "parameters": [CLIENT_ID_HEADER],
                "requestBody": json_body(_ref("MotionRequest")),
                "responses": {
                    "200": _json(_ref("MotionState"), "The command now in force."),
                    "409": _json(_ref("NotInControl"), "Another client holds the motion lease; resend with take_over."),
                } | _errors(400, 401, 413, 415, 429),
            },
            "get": {
                "operationId": "motionState", "summary": "The motion command in force.",
                "responses": {"200": _json(_ref("MotionState"), "Motion.")} | _errors(401),
            },
        },
        "/events": {"get": {
            "operationId": "events", "summary": "Long-poll for touch, presence and interaction events.",
            "parameters": [after, _query("timeout", {"type": "number", "minimum": 0, "maximum": 300}, "Longest wait in seconds (capped by config).")],
            "responses": {"200": _json(_ref("EventBatch"), "Events after `after`.")} | _errors(400, 401),
        }},
        "/events/stream": {"get": {
            "operationId": "eventStream", "summary": "Server-Sent Events; `id` is the seq, resume with Last-Event-ID.",
            "parameters": [after, TOKEN_QUERY, {"name": "Last-Event-ID", "in": "header", "required": False, "schema": resume}],
            "x-streaming": True,
            "responses": {"200": {"description": "text/event-stream of Event objects.", "content": {"text/event-stream": {"schema": {"type": "string"}}}}} | _errors(400, 401),
        }},
        "/events/ws": {"get": {
            "operationId": "eventSocket", "summary": "WebSocket: each text message is one Event object; motion commands may go the other way.",
            "parameters": [after, TOKEN_QUERY], "x-streaming": True,
            "responses": {"101": {"description": "Switching to WebSocket."}} | _errors(400, 401),
        }},
        "/face": {"put": {
            "operationId": "face", "summary": "The wearer's face (one JPEG) or a looping avatar (multipart JPEG frames); newest wins.",
            "description": "Each frame's size is read from its JPEG header before anything is decoded: above "
            "`max_face_pixels` (width x height) the upload is refused with 413 image_too_large. Rate limited per "
            "client together with the wearer actions.",
            "parameters": [CLIENT_ID_HEADER, _query("fps", {"type": "number", "minimum": 0.5, "maximum": 60}, "Avatar loop rate.")],
            "requestBody": {"required": True, "content": {
                "image/jpeg": {"schema": {"type": "string", "contentMediaType": "image/jpeg"}},
                "multipart/form-data": {"schema": {"type": "object", "properties": {"frame": {"type": "array", "items": {"type": "string", "contentMediaType": "image/jpeg"}}}}},
            }},
            "responses": {"200": _json({"type": "object", "required": ["frames"], "properties": {"frames": {"type": "integer"}, "fps": {"type": ["number", "null"]}, "bytes": {"type": "integer"}}}, "Shown until replaced or cleared.")} | _errors(400, 401, 413, 415, 429),
        }, "delete": {
            "operationId": "clearFace", "summary": "Clear the wearer's face: the projector shows its default avatar again.",
            "parameters": [CLIENT_ID_HEADER],
            "responses": {"200": _json({"type": "object", "required": ["cleared"], "properties": {"cleared": {"const": True}}}, "Cleared.")} | _errors(401, 429),
        }},
        "/speech": {
            "post": {
                "operationId": "speechIn", "summary": "A chunk of the wearer's speech (PCM16 WAV, any rate; resampled).",
                "parameters": [CLIENT_ID_HEADER],
                "requestBody": {"required": True, "content": {"audio/wav": {"schema": {"type": "string", "contentMediaType": "audio/wav"}}}},
                "responses": {"202": _json({"type": "object", "required": ["samples", "rate", "ms"], "properties": {"samples": {"type": "integer"}, "rate": {"type": "integer"}, "ms": {"type": "number"}}}, "Queued for the speaker.")} | _errors(400, 401, 413, 415, 429),
            },
            "get": {
                "operationId": "speechOut", "summary": "Room audio captured after `after` as one PCM16 WAV; X-Speech-Seq is the next `after`.",
                "parameters": [
                    _query("after", {"type": "integer", "minimum": 0, "maximum": MAX_SEQ}, "The last X-Speech-Seq received."),
                    _query("timeout", {"type": "number", "minimum": 0, "maximum": 5}, "Longest wait in seconds."),
                ],
                "responses": {
                    "200": {"description": "WAV.", "headers": {"X-Feelium-Capture-T": CAPTURE_T}, "content": {"audio/wav": {"schema": {"type": "string", "contentMediaType": "audio/wav"}}}},
                    "204": {"description": "No audio within the timeout."},
                } | _errors(400, 401),
            },
        },
        "/actions/{action}": {"post": {
            "operationId": "wearerAction", "summary": "A wearer action for the interaction engine (heart, palm, shimmer).",
            "parameters": [{"name": "action", "in": "path", "required": True, "schema": {"type": "string", "enum": [a for a in ACTIONS if a != "guess"]}}, CLIENT_ID_HEADER],
            "requestBody": json_body({"type": "object", "additionalProperties": False}, required=False),
            "responses": {"202": _json(_ref("WearerAction"), "Published.")} | _errors(400, 401, 404, 413, 415, 429),
        }},
        "/actions/guess": {"post": {
            "operationId": "guess", "summary": "The wearer's guess of the partner's drawing.",
            "requestBody": json_body({
                "type": "object", "required": ["word"], "additionalProperties": False,
                "properties": {"word": {"type": "string", "minLength": 1, "maxLength": MAX_WORD, "pattern": "\\S"}},
            }),
            "parameters": [CLIENT_ID_HEADER],
            "responses": {"202": _json(_ref("WearerAction"), "Published.")} | _errors(400, 401, 413, 415, 429),
        }},
        "/sim": {"get": {
            "operationId": "sim", "summary": "Whether simulated touches are available.",
            "responses": {"200": _json({"type": "object", "required": ["sim"], "properties": {"sim": {"type": "boolean"}}}, "Sim mode.")} | _errors(401),
        }},
        "/sim/press": {"post": {
            "operationId": "simPress", "summary": "Press or hover a simulated fingertip on the rear camera (sim mode only; 409 outside the frame).",
            "requestBody": json_body(_ref("SimPress")),
            "responses": {"202": _json({"type": "object"}, "Pressed.")} | _errors(400, 401, 404, 409, 413, 415),
        }},
        "/sim/release": {"post": {
            "operationId": "simRelease", "summary": "Lift the simulated fingertip (sim mode only).",
            "requestBody": json_body({"type": "object", "additionalProperties": False}, required=False),
            "responses": {"202": _json({"type": "object"}, "Released.")} | _errors(400, 401, 404, 409, 413, 415),
        }},
    }  # fmt: skip
    _add_stream_messages(paths)
    return {
        "openapi": "3.1.0",
        "info": {
            "title": "Feelium headset API",
            "version": "1.0.0",
            "description": "The link between the wearer's headset and the blimp. Every endpoint but /health "
            "needs the bearer token; video, SSE and WebSocket also accept ?token=. " + SKIN_UV,
        },
        "servers": [{"url": "/api/v1"}],
        "security": [{"bearer": []}],
        "components": {
            "securitySchemes": {"bearer": {"type": "http", "scheme": "bearer"}},
            "schemas": schemas | {"Lens": LENS_SCHEMA},
        },
        "paths": paths | lens_paths(),
    }
