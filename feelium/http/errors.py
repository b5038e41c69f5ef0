"""Every error the API returns is a JSON body that says what was wrong.

Handlers raise :class:`ApiError` (or aiohttp's own HTTP exceptions, e.g. the
413 of a too-large body); the middleware turns both into
``{"error": code, "message": text}`` with the right status. Anything else
is a bug: it is logged with its traceback, counted, and answered with a 500
JSON body, never a dropped connection or an HTML page.
"""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable
from typing import Any

from aiohttp import web

log = logging.getLogger(__name__)

_CODES = {
    400: "bad_request",
    401: "unauthorized",
    403: "forbidden",
    404: "not_found",
    405: "method_not_allowed",
    409: "conflict",
    413: "payload_too_large",
    415: "unsupported_media_type",
    422: "unprocessable",
    429: "too_many_requests",
}


class ApiError(Exception):
    """An HTTP error with a machine code and a human message."""

    def __init__(
        self,
        status: int,
        message: str,
        code: str | None = None,
        headers: dict[str, str] | None = None,
        extra: dict[str, Any] | None = None,
    ) -> None:
        super().__init__(message)
        self.status = status
        self.code = code or _CODES.get(status, "error")
        self.message = message
        self.headers = headers or {}
        self.extra = extra or {}  # more fields for the body, e.g. who holds the motion lease


def error_response(
    status: int, message: str, code: str | None = None, headers: Any = None, extra: dict[str, Any] | None = None
) -> web.Response:
    body = {"error": code or _CODES.get(status, "error"), "message": message} | (extra or {})
    return web.json_response(body, status=status, headers=headers)


def _passthrough_headers(exc: web.HTTPException) -> dict[str, str]:
    keep = ("Allow", "Retry-After", "WWW-Authenticate")
    return {k: v for k, v in exc.headers.items() if k in keep}


Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


@web.middleware
async def json_errors(request: web.Request, handler: Handler) -> web.StreamResponse:
    """Turn every failure into a JSON error body; count the unexpected ones."""
    try:
        return await handler(request)
    except ApiError as exc:
        return error_response(exc.status, exc.message, exc.code, exc.headers, exc.extra)
    except web.HTTPException as exc:
        if exc.status < 400:
            raise
        message = exc.text if exc.text and not exc.text.startswith(f"{exc.status}:") else exc.reason
        if exc.status == 413:
            message = f"request body too large: {exc.reason}; see max_*_bytes in [http]"
        elif exc.status == 405:
            message = f"{request.method} is not allowed on {request.path}"
        elif exc.status == 404:
            message = f"no such endpoint: {request.path}"
        return error_response(exc.status, message, None, _passthrough_headers(exc))
    except (ConnectionResetError, ConnectionError):
        raise
    except Exception:
        log.exception("unexpected error in %s %s", request.method, request.path)
        stats = request.app.get(ERROR_STATS)
        if stats is not None:
            stats["internal_errors"] = stats.get("internal_errors", 0) + 1
        return error_response(500, "internal error (logged on the blimp)", "internal")


ERROR_STATS: web.AppKey[dict[str, int]] = web.AppKey("error_stats", dict)
