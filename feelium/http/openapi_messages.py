"""The streamed messages of the headset API as JSON Schemas: events, the state snapshot, speech stream frames.

OpenAPI 3.1 describes request and response bodies, not what flows inside an
SSE stream or a WebSocket, so these schemas live in ``components/schemas`` and
each streaming operation names its messages in ``x-sse-events`` or
``x-websocket-messages`` (``server`` -> client and ``client`` -> server, text
and binary). ``tests/http/test_message_schemas.py`` validates live messages of
every kind against them, so a client generated from the document reads what
the daemon really sends. Kept apart from ``openapi.py`` so the two grow
without stepping on each other.
"""

from __future__ import annotations

from typing import Any

from feelium.http.speech_stream import FRAME_VERSION, HEADER_BYTES
from feelium.motion import MAX_HOLD_S, MOTION_NAMES

NUM = {"type": "number"}
NUM_OR_NULL = {"type": ["number", "null"]}
STR_OR_NULL = {"type": ["string", "null"]}


def _ref(name: str) -> dict[str, str]:
    return {"$ref": f"#/components/schemas/{name}"}


def _strict(required: list[str], properties: dict[str, Any], description: str) -> dict[str, Any]:
    return {"type": "object", "required": required, "properties": properties, "additionalProperties": False, "description": description}


RESUME_TEXT = (
    "Reconnect and resume: every event has a sequence number `seq`, monotonic within a daemon run, and the run's "
    "`epoch` (8 hex digits, new at each daemon start). Keep `EPOCH:SEQ` of the last event handled and reconnect with "
    "it (`?after=` for long-poll and WebSocket, `Last-Event-ID` for SSE, whose `id` is that token): the events after "
    "it follow, none is lost while the ring (`event_ring_size`) still holds them. When it does not (the client fell "
    "further behind, or the epoch is another run's because the daemon restarted), the client gets a reset instead: "
    "SSE and WebSocket send a `reset` message whose `event.state` is the current state snapshot and whose `seq` is the "
    "newest number, and only newer events follow; the long-poll answers `reset: true` with `state`. Old events are "
    "never replayed and numbers never go backwards within an epoch. Reconnect after a drop with a backoff (1 s, "
    "doubling to about 30 s); SSE's `retry:` is 1000 ms. A server that closes a stream it judged stalled (nothing "
    "accepted for `stream_write_timeout_s`) or a missed WebSocket pong (every `keepalive_s`) ends the connection "
    "without a message: resume as above."
)

SPEECH_STREAM_TEXT = (
    "Room audio as it is captured, and optionally the wearer's speech the other way, on one WebSocket. The server "
    "first sends a text `hello` (SpeechStreamHello), then one binary message per captured chunk (about every 40 ms): "
    f"a {HEADER_BYTES}-byte little-endian header (SpeechFrameHeader: version u16 at 0, header_bytes u16 at 2, rate "
    "u32 at 4, seq u64 at 8, capture_t f64 at 16, dropped u64 at 24) followed by PCM16 mono little-endian samples "
    "starting at `header_bytes`. `capture_t` is when the chunk's last sample was captured, on the daemon clock of "
    "GET /clock; `seq` numbers chunks as X-Speech-Seq of GET /speech does; `dropped` counts the chunks this stream "
    "skipped so far. Nothing is queued for a slow client: a frame that finds more than `speech_stream_backlog_ms` "
    "of audio still unacknowledged on the socket is dropped (and counted in `dropped`), and a client that accepts "
    "nothing for `stream_write_timeout_s` is disconnected and its slot freed. Slots: `max_speech_streams_per_client` "
    "per client, `max_speech_streams` in all (429 above). Each binary message the client sends is one chunk of its "
    "speech for the blimp's speaker: PCM16 mono little-endian at `?rate=` (default the hello's `rate`), at most "
    "`max_speech_bytes`, under the same per-client `speech_rate_per_s` limit as POST /speech; a refused chunk is "
    "dropped and the client gets a text `notice` (SpeechStreamNotice) at most once a second; a message over the size "
    "limit closes the socket (1009). Text messages from the client are ignored. Resume after a reconnect with "
    "`?after=<last seq>` to get the chunks still held (`capture_keep_ms`); without it only new audio follows."
)


def message_schemas() -> dict[str, Any]:
    """``components/schemas`` entries of every streamed message (events, state snapshot, speech stream)."""
    touch = _strict(
        ["id", "phase", "kind", "t", "x", "y", "u", "v", "depth", "area", "anchor"],
        {
            "id": {"type": "integer", "minimum": 0, "description": "The contact; all its phases share it."},
            "phase": {"enum": ["down", "move", "up"]},
            "kind": {"enum": ["tap", "hold", "swipe", None], "description": "null while undecided."},
            "t": NUM_OR_NULL | {"description": "When the rear camera saw it: daemon clock, s (GET /clock)."},
            "x": NUM_OR_NULL | {"description": "Rear camera pixels."},
            "y": NUM_OR_NULL,
            "u": NUM_OR_NULL | {"description": "0..1 across the membrane, left to right (skin coordinates)."},
            "v": NUM_OR_NULL | {"description": "0..1 across the membrane, top to bottom."},
            "depth": NUM_OR_NULL | {"description": "How hard (relative shadow depth, 0..1)."},
            "area": {"type": "integer", "minimum": 0, "description": "Contact area, rear camera pixels."},
            "anchor": NUM_OR_NULL | {"description": "How anchored (sustained) the contact is, 0..1."},
            "px": NUM_OR_NULL | {"description": "Projector pixels (only with a projector calibration; null off the map)."},
            "py": NUM_OR_NULL,
            "region": STR_OR_NULL | {"description": "The skin region touched (only with a projector calibration)."},
            "contact": {
                "enum": ["finger", "palm", "hug"],
                "description": "What touched, from the contact's footprint (kind is the gesture in time).",
            },
            "contact_area_mm2": NUM_OR_NULL | {"description": "The footprint's area on the membrane, mm^2 (null: scale unknown)."},
            "major_mm": NUM_OR_NULL | {"description": "The footprint's long axis, mm (null: scale unknown)."},
            "minor_mm": NUM_OR_NULL | {"description": "The footprint's short axis, mm (null: scale unknown)."},
            "elongation": NUM_OR_NULL | {"description": "Long axis over short axis."},
            "orientation_deg": NUM_OR_NULL | {"description": "The long axis from the camera's x axis (image y down), 0..180."},
        },
        "One phase of one contact on the membrane.",
    )
    presence = _strict(
        ["phase", "t", "x", "y", "azimuth_deg", "elevation_deg", "size", "peak_rise_c"],
        {
            "phase": {"enum": ["approach", "update", "leave"]},
            "t": NUM_OR_NULL, "x": NUM_OR_NULL | {"description": "Thermal sensor pixels (32x24)."}, "y": NUM_OR_NULL,
            "azimuth_deg": NUM_OR_NULL | {"description": "Bearing, positive to the right."},
            "elevation_deg": NUM_OR_NULL | {"description": "Bearing, positive up."},
            "size": {"type": "integer", "minimum": 0, "description": "Warm pixels."},
            "peak_rise_c": NUM_OR_NULL | {"description": "Warmest pixel above the room, degC."},
        },
        "A warm body near the blimp (thermal camera).",
    )  # fmt: skip
    interaction = _strict(
        ["name", "phase", "t", "x", "y", "region"],
        {
            "name": {"enum": ["greeting_pat", "palm_to_palm", "peck", "drawing", "hug", "invite"]},
            "phase": {"enum": [
                "start", "stroke", "stroke_end", "end", "ignite", "no_round", "wrong_guess", "pat", "bloom",
                "returned", "partner", "wearer", "merge", "shimmer", "accepted",
            ]},
            "t": NUM_OR_NULL, "x": NUM_OR_NULL | {"description": "Rear camera pixels, when located."}, "y": NUM_OR_NULL,
            "region": STR_OR_NULL,
            "stroke": {"type": "integer", "description": "drawing stroke / stroke_end: the stroke's number."},
            "points": {"type": "array", "items": {"type": "array", "prefixItems": [NUM, NUM], "minItems": 2, "maxItems": 2},
                       "description": "drawing stroke: new [u, v] points of the stroke."},
            "round": {"type": "integer", "description": "drawing start / ignite: the round."},
            "taps": {"type": "integer", "description": "greeting_pat pat: taps so far."},
            "who": {"enum": ["partner", "wearer"], "description": "palm_to_palm end: whose palm left."},
            "area": {"type": "number", "description": "palm_to_palm partner, hug start: contact area."},
            "reason": {"type": "string", "description": "drawing end: why."},
            "word": {"type": "string", "description": "drawing end / ignite: the word drawn."},
            "guess": {"type": "string", "description": "drawing ignite / wrong_guess / no_round: the wearer's guess."},
        },
        "An exchange the interaction engine recognised, with its per-exchange fields.",
    )  # fmt: skip
    wearer = _strict(
        ["action", "t"],
        {"action": {"enum": ["heart", "palm_raise", "palm_lower", "shimmer", "guess"]}, "t": NUM_OR_NULL,
         "word": {"type": "string", "description": "guess only."}},
        "A wearer action as it was accepted.",
    )  # fmt: skip
    state = {
        "type": "object",
        "description": "What each service publishes, as it publishes it (GET /state `services`, reset `event.state`). "
        "Parts appear once their service has reported; a service may add fields.",
        "properties": {
            "touch": {"type": "object", "properties": {
                "t": NUM, "activity": {"type": "boolean"}, "anchor": NUM_OR_NULL, "depth_max": NUM_OR_NULL,
                "contacts": {"type": "array", "items": {"type": "object"}}, "backend": {"type": "string"},
            }},
            "presence": {"type": "object", "properties": {
                "present": {"type": "boolean"}, "t": NUM, "x": NUM_OR_NULL, "y": NUM_OR_NULL,
                "size": {"type": "integer"}, "peak_rise_c": NUM_OR_NULL, "ambient_c": NUM_OR_NULL,
            }},
            "flight": {"type": "object", "properties": {
                "altitude_m": NUM_OR_NULL, "altitude_target_m": NUM_OR_NULL, "heading_deg": NUM_OR_NULL,
                "heading_target_deg": NUM_OR_NULL, "battery_v": NUM_OR_NULL, "battery": STR_OR_NULL,
                "link": {"type": "string"}, "mode": STR_OR_NULL, "motors_us": {"type": "array", "items": NUM},
            }},
        },
        "additionalProperties": {"type": "object"},
    }  # fmt: skip

    def envelope(kind: str, body: dict[str, Any]) -> dict[str, Any]:
        return _strict(
            ["seq", "epoch", "type", "event"],
            {"seq": {"type": "integer", "minimum": 0}, "epoch": {"type": "string", "pattern": "^[0-9a-f]{8}$"},
             "type": {"const": kind}, "event": body},
            f"A `{kind}` event.",
        )  # fmt: skip

    reset = envelope("reset", _strict(["state"], {"state": _ref("ServicesState")}, "The state now."))
    reset["description"] = ("SSE and WebSocket only: events were lost (the ring no longer holds them) or the epoch is "
                            "another run's. `seq` is the newest number; only events above it follow.")
    return {
        "TouchEvent": touch,
        "PresenceEvent": presence,
        "InteractionEvent": interaction,
        "WearerActionEvent": wearer,
        "ServicesState": state,
        "Event": {
            "description": "The envelope every event transport carries (`seq`, `epoch`, `type`, `event`); `type` says "
            "which schema `event` follows. " + RESUME_TEXT,
            "oneOf": [
                envelope("touch", _ref("TouchEvent")), envelope("presence", _ref("PresenceEvent")),
                envelope("interaction", _ref("InteractionEvent")), envelope("wearer_action", _ref("WearerActionEvent")),
            ],
        },
        "ResetMessage": reset,
        "StreamMessage": {"description": "What SSE and WebSocket event streams send.", "oneOf": [_ref("Event"), _ref("ResetMessage")]},
        "MotionSocketCommand": {
            "type": "object", "required": ["type", "command"], "additionalProperties": False,
            "description": "A motion command sent on the events WebSocket (text): POST /motion's body (MotionRequest) "
            "with `type` and an optional `id` the reply echoes. Same rules as POST /motion: a `stop` is applied at once "
            "from any client; other commands are charged to the client's motion rate limit and need the lease.",
            "properties": {
                "type": {"const": "motion"},
                "id": {"type": ["integer", "string", "null"], "minimum": 0, "maximum": 2**53, "maxLength": 64,
                       "description": "Echoed in the reply, to match replies with commands."},
                "command": {"type": "string", "enum": list(MOTION_NAMES)},
                "hold_ms": {"type": "number", "minimum": 1, "maximum": 1000 * MAX_HOLD_S, "default": 500},
                "take_over": {"type": "boolean", "default": False},
            },
        },
        "MotionReply": _strict(
            ["type", "id", "status", "body"],
            {
                "type": {"const": "motion_reply"},
                "id": {"type": ["integer", "string", "null"], "description": "The command's `id` (null when it sent none)."},
                "status": {"type": "integer", "description": "What POST /motion would have answered: 200, 400, 409 or 429."},
                "body": {"anyOf": [_ref("MotionState"), _ref("NotInControl"), _ref("Error")],
                         "description": "POST /motion's response body for that status."},
                "retry_after_s": {"type": "integer", "minimum": 1, "description": "429 only: POST /motion's Retry-After."},
            },
            "The reply to each MotionSocketCommand, in the order they were sent (text).",
        ),
        "SpeechStreamHello": _strict(
            ["type", "version", "header_bytes", "format", "channels", "rate", "in_rate", "after", "max_in_bytes", "in_rate_per_s"],
            {
                "type": {"const": "hello"}, "version": {"const": FRAME_VERSION}, "header_bytes": {"const": HEADER_BYTES},
                "format": {"const": "pcm16le"}, "channels": {"const": 1},
                "rate": {"type": "integer", "description": "Sample rate of the frames that follow, Hz."},
                "in_rate": {"type": "integer", "description": "The rate the server reads the client's binary messages at (?rate=)."},
                "after": {"type": "integer", "minimum": 0, "description": "Frames follow from the chunk after this one."},
                "max_in_bytes": {"type": "integer", "description": "Largest binary message the client may send."},
                "in_rate_per_s": {"type": "number", "description": "Client messages per second accepted (sustained)."},
            },
            "The first message of a speech stream (text).",
        ),
        "SpeechStreamNotice": _strict(
            ["type", "error", "message", "refused_in"],
            {"type": {"const": "notice"}, "error": {"enum": ["bad_request", "too_many_requests"]},
             "message": {"type": "string"}, "refused_in": {"type": "integer", "minimum": 1,
                                                           "description": "Client messages refused so far on this stream."}},
            "A client message was refused (at most one notice a second; text).",
        ),  # fmt: skip
        "SpeechFrameHeader": _strict(
            ["version", "header_bytes", "rate", "seq", "capture_t", "dropped", "samples"],
            {
                "version": {"type": "integer", "minimum": 1, "description": "u16 LE at byte 0."},
                "header_bytes": {"type": "integer", "minimum": HEADER_BYTES, "description": "u16 LE at byte 2: where the samples start."},
                "rate": {"type": "integer", "minimum": 1, "description": "u32 LE at byte 4: Hz."},
                "seq": {"type": "integer", "minimum": 1, "description": "u64 LE at byte 8: the chunk's number (X-Speech-Seq)."},
                "capture_t": {"type": "number", "description": "f64 LE at byte 16: last sample captured, daemon clock, s."},
                "dropped": {"type": "integer", "minimum": 0, "description": "u64 LE at byte 24: chunks skipped on this stream so far."},
                "samples": {"type": "integer", "minimum": 0, "description": "Not in the header: (message length - header_bytes) / 2."},
            },
            "The binary frame's header, field by field (the binary message itself is header then PCM16 samples).",
        ),
    }


def event_stream_extensions() -> dict[str, dict[str, Any]]:
    """The ``x-`` extensions and descriptions of the event operations, keyed by operationId."""
    return {
        "events": {"description": RESUME_TEXT},
        "eventStream": {
            "description": "Each message: `id: EPOCH:SEQ`, `event: <type>`, `data: <StreamMessage JSON>`; comment "
            "lines (`: keepalive`) every `keepalive_s`; `retry: 1000` first. " + RESUME_TEXT,
            "x-sse-events": {
                "touch": _ref("Event"), "presence": _ref("Event"), "interaction": _ref("Event"),
                "wearer_action": _ref("Event"), "reset": _ref("ResetMessage"),
            },
        },
        "eventSocket": {
            "description": "Each text message is one StreamMessage, or a MotionReply to a motion command the client "
            "sent on the socket (MotionSocketCommand: POST /motion's body and rules, one reply per command); other "
            "client messages are ignored. The server pings every `keepalive_s`. " + RESUME_TEXT,
            "x-websocket-messages": {"server": {"text": {"oneOf": [_ref("StreamMessage"), _ref("MotionReply")]}},
                                     "client": {"text": _ref("MotionSocketCommand")}},
        },
    }


def speech_stream_path(errors: dict[str, Any], client_params: list[dict[str, Any]]) -> dict[str, Any]:
    """``/speech/stream``: the operation (``errors``: the shared 4xx responses; ``client_params``: token and client id)."""
    query = lambda name, schema, text: {"name": name, "in": "query", "required": False, "schema": schema, "description": text}  # noqa: E731
    return {"get": {
        "operationId": "speechStream",
        "summary": "WebSocket: room audio as binary PCM16 frames with capture time, and the wearer's speech back.",
        "description": SPEECH_STREAM_TEXT,
        "parameters": [
            *client_params,
            query("after", {"type": "integer", "minimum": 0, "maximum": 2**53},
                  "Resume after this chunk number (a frame's seq); omitted = only new audio."),
            query("rate", {"type": "integer", "minimum": 8000, "maximum": 48000},
                  "Sample rate of the client's binary messages (default the server's)."),
        ],
        "x-streaming": True,
        "x-websocket-messages": {
            "server": {"text": {"oneOf": [_ref("SpeechStreamHello"), _ref("SpeechStreamNotice")]},
                       "binary": {"header": _ref("SpeechFrameHeader"), "payload": "PCM16 mono little-endian samples"}},
            "client": {"binary": {"payload": "PCM16 mono little-endian samples at ?rate=, at most max_speech_bytes"}},
        },
        "responses": {"101": {"description": "Switching to WebSocket."}} | errors,
    }}  # fmt: skip


# Every `error` code with its status and meaning (docs/api.md, Errors, holds the same table).
ERROR_CODES: dict[str, tuple[int, str]] = {
    "bad_request": (400, "Malformed JSON, unknown fields, values out of range, bad query parameters, not a JPEG / PCM16 WAV, a request the HTTP parser rejects."),
    "unauthorized": (401, "Missing or wrong token (WWW-Authenticate: Bearer)."),
    "host_not_allowed": (403, "A Host that is not one of the blimp's names (DNS rebinding)."),
    "origin_not_allowed": (403, "A browser page from an origin not in cors_origins."),
    "pairing_failed": (403, "POST /pair with a wrong, used or expired code."),
    "not_found": (404, "Unknown path, static file, camera or action."),
    "no_frame": (404, "No frame published yet."),
    "not_sim": (404, "Sim endpoints outside sim mode."),
    "method_not_allowed": (405, "Wrong method on a known path (with Allow)."),
    "not_in_control": (409, "Motion from a client that does not hold the motion lease (body: NotInControl)."),
    "token_not_rotatable": (409, "POST /token/rotate while the token is set in [http] token."),
    "conflict": (409, "The simulator refused the request."),
    "outside_frame": (409, "A simulated press outside the rear camera's frame."),
    "payload_too_large": (413, "Body over the configured limit."),
    "image_too_large": (413, "A face JPEG declaring more than max_face_pixels."),
    "unsupported_media_type": (415, "Wrong Content-Type (JSON bodies must be application/json, UTF-8)."),
    "too_many_requests": (429, "This client's rate limit or a stream limit (with Retry-After)."),
    "uploads_busy": (429, "[http] max_uploads_in_flight face uploads are being received already (Retry-After: 1)."),
    "internal": (500, "A bug (logged and counted); never the answer to a bad request."),
}  # fmt: skip


def error_schema() -> dict[str, Any]:
    """The body of every error: ``{"error": code, "message": sentence}``, the codes listed in ``x-error-codes``."""
    return {
        "type": "object",
        "required": ["error", "message"],
        "description": "Every 4xx (and any 5xx) body: a machine code (`error`, one of x-error-codes; switch on it, "
        "not on the message) and a sentence for people. Some errors add fields (409 not_in_control: see NotInControl). "
        "A 429 carries Retry-After (seconds).",
        "properties": {"error": {"type": "string", "pattern": "^[a-z_]+$"}, "message": {"type": "string"}},
        "x-error-codes": {code: {"status": status, "when": when} for code, (status, when) in ERROR_CODES.items()},
    }
