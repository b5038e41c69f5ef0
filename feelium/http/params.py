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


async def read_json_object(request: web.Request, limit: int, *, required: bool = True) -> dict[str, Any]:
    """A JSON object body; an empty body is ``{}`` when not ``required``."""
    body = await read_body(request, limit)
    if not body.strip():
        if required:
            raise ApiError(400, "expected a JSON object body")
        return {}
    ctype = request.content_type
    if ctype not in ("application/json", "text/plain", "application/octet-stream"):
        raise ApiError(415, f"expected Content-Type application/json, got {ctype}")
    try:
        value = json.loads(body)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ApiError(400, f"body is not valid JSON: {exc}") from exc
    if not isinstance(value, dict):
        raise ApiError(400, f"expected a JSON object, got {type(value).__name__}")
    return value


def check_keys(obj: dict[str, Any], allowed: set[str]) -> None:
    unknown = sorted(set(obj) - allowed)
    if unknown:
        raise ApiError(400, f"unknown field(s) {', '.join(unknown)}; allowed: {', '.join(sorted(allowed)) or 'none'}")


def number_field(obj: dict[str, Any], name: str, default: float | None, lo: float, hi: float) -> float | None:
    """A finite number within [lo, hi]; booleans are not numbers."""
    if name not in obj or obj[name] is None:
        if default is None and name in obj:
            return None
        return default
    value = obj[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ApiError(400, f"{name} must be a number, got {json.dumps(value)[:40]}")
    if not lo <= value <= hi:
        raise ApiError(400, f"{name} must be within {lo:g}..{hi:g}, got {value:g}")
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
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ApiError(400, f"query parameter {name} must be within {lo:g}..{hi:g}, got {raw[:40]}")
    return value
