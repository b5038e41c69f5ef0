"""Reading request bodies and query parameters with limits and errors that name the field."""

from __future__ import annotations

import json
import math
from typing import Any

from aiohttp import web

from feelium.http.errors import ApiError


async def read_body(request: web.Request, limit: int) -> bytes:
    """The whole body, or 413 as soon as it exceeds ``limit`` (declared or streamed)."""
    declared = request.content_length
    if declared is not None and declared > limit:
        raise ApiError(413, f"request body of {declared} bytes exceeds the limit of {limit} bytes")
    chunks: list[bytes] = []
    size = 0
    async for chunk in request.content.iter_chunked(65536):
        size += len(chunk)
        if size > limit:
            raise ApiError(413, f"request body exceeds the limit of {limit} bytes")
        chunks.append(chunk)
    return b"".join(chunks)


JSON_TYPES = ("application/json",)


def json_depth(text: str) -> int:
    """How deeply arrays and objects nest in ``text`` (brackets inside strings do not count).

    Checked before parsing: Python's ``json`` recurses once per level and a few thousand
    levels raise ``RecursionError`` (a 500) instead of a parse error.
    """
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def _no_constants(name: str) -> Any:
    raise ValueError(f"{name} is not JSON")


def parse_json(body: bytes, max_depth: int) -> Any:
    """Strict JSON: UTF-8 only, at most ``max_depth`` levels, no ``NaN``/``Infinity``; 400 otherwise."""
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ApiError(400, f"body is not valid UTF-8 (byte {exc.start})") from None
    depth = json_depth(text) if text.count("[") + text.count("{") > max_depth else 0
    if depth > max_depth:
        raise ApiError(400, f"JSON nests {depth} levels deep; at most {max_depth} are accepted")
    try:
        return json.loads(text, parse_constant=_no_constants)
    except ValueError as exc:  # includes integers past Python's digit limit
        raise ApiError(400, f"body is not valid JSON: {str(exc)[:200]}") from None


async def read_json_object(request: web.Request, limit: int, max_depth: int, *, required: bool = True) -> dict[str, Any]:
    """A JSON object body of ``application/json``; an empty body is ``{}`` when not ``required``."""
    return json_object(await read_body(request, limit), request, max_depth, required=required)


def json_object(body: bytes, request: web.Request, max_depth: int, *, required: bool = True) -> dict[str, Any]:
    """``body`` (already read) as the JSON object ``request``'s content type must declare."""
    if not body.strip():
        if required:
            raise ApiError(400, "expected a JSON object body")
        return {}
    ctype = request.content_type
    if ctype not in JSON_TYPES:
        raise ApiError(415, f"expected Content-Type application/json, got {ctype[:80]}")
    charset = request.charset
    if charset is not None and charset.lower() not in ("utf-8", "utf8"):
        raise ApiError(415, f"JSON must be UTF-8, got charset={charset[:40]}")
    value = parse_json(body, max_depth)
    if not isinstance(value, dict):
        raise ApiError(400, f"expected a JSON object, got {type(value).__name__}")
    return value


def check_keys(obj: dict[str, Any], allowed: set[str]) -> None:
    unknown = sorted(set(obj) - allowed)
    if unknown:
        raise ApiError(400, f"unknown field(s) {', '.join(unknown)}; allowed: {', '.join(sorted(allowed)) or 'none'}")


def number_field(obj: dict[str, Any], name: str, default: float | None, lo: float, hi: float) -> float | None:
    """A finite number within [lo, hi]; booleans are not numbers.

    Integers are compared exactly before any conversion: ``float(10**400)`` overflows, and so would
    formatting one with ``:g`` in the error message.
    """
    if name not in obj or obj[name] is None:
        if default is None and name in obj:
            return None
        return default
    value = obj[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (isinstance(value, float) and not math.isfinite(value)):
        raise ApiError(400, f"{name} must be a number, got {json.dumps(value)[:40]}")
    if not lo <= value <= hi:
        shown = f"{value:g}" if isinstance(value, float) else (str(value) if abs(value) < 10**15 else "a larger integer")
        raise ApiError(400, f"{name} must be within {lo:g}..{hi:g}, got {shown}")
    return float(value)


def query_number(request: web.Request, name: str, default: float, lo: float, hi: float, *, integer: bool = False) -> float:
    """A query parameter as a number within [lo, hi]."""
    raw = request.query.get(name)
    if raw is None or raw == "":
        return default
    try:
        value = int(raw) if integer else float(raw)
    except ValueError:
        kind = "an integer" if integer else "a number"
        raise ApiError(400, f"query parameter {name} must be {kind}, got {raw[:40]!r}") from None
    # the bounds first: math.isfinite(10**400) overflows converting the int to a float
    if not (lo <= value <= hi and math.isfinite(value)):
        raise ApiError(400, f"query parameter {name} must be within {lo:g}..{hi:g}, got {raw[:40]}")
    return value
