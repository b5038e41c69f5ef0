"""Host, CORS and token middlewares: the room's Wi-Fi reaches the blimp, only the wearer's client may use it."""

from __future__ import annotations

from collections.abc import Awaitable, Callable

from aiohttp import web

from feelium.http.auth import presented_token
from feelium.http.context import ctx
from feelium.http.errors import error_response
from feelium.http.hosts import HostAllowList

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]

API_PREFIX = "/api/v1"
# Reachable without the token: health (for monitors), the API description and the static client
# (neither holds a secret; the client reads the token from its URL fragment).
# Pairing is public too: its body carries the short-lived code that stands in for the token.
PUBLIC_API_PATHS = frozenset({f"{API_PREFIX}/health", f"{API_PREFIX}/openapi.json", f"{API_PREFIX}/pair"})
ALLOWED_METHODS = "GET, POST, PUT, DELETE, OPTIONS"
ALLOWED_HEADERS = "Authorization, Content-Type, Last-Event-ID, X-Feelium-Client"


def parse_origins(text: str) -> frozenset[str]:
    """The configured comma-separated origins, normalised (no trailing slash, lower-case)."""
    return frozenset(o.strip().rstrip("/").lower() for o in text.split(",") if o.strip())


def own_origin(request: web.Request) -> str:
    return f"{request.scheme}://{request.host}".lower()


def origin_allowed(request: web.Request, origin: str, allowed: frozenset[str]) -> bool:
    origin = origin.rstrip("/").lower()
    return origin == own_origin(request) or origin in allowed


def needs_token(path: str) -> bool:
    return path.startswith(API_PREFIX) and path not in PUBLIC_API_PATHS


def local_address(request: web.Request) -> str | None:
    """The address the request's connection arrived on (the server's side of the socket)."""
    sockname = request.transport.get_extra_info("sockname") if request.transport is not None else None
    return str(sockname[0]) if isinstance(sockname, (tuple, list)) and sockname else None


def make_host_middleware(allowed: HostAllowList) -> Callable[..., Awaitable[web.StreamResponse]]:
    """403 for a ``Host`` that is not one of the blimp's names (DNS rebinding), before anything else runs.

    Checked first because the same-origin rule below trusts ``Host``: only a checked Host makes an
    ``Origin`` equal to ``scheme://Host`` mean "the blimp's own page".
    """

    @web.middleware
    async def host_check(request: web.Request, handler: Handler) -> web.StreamResponse:
        host = request.headers.get("Host")
        if not allowed.allows(host, local_address(request)):
            ctx(request).count("host_not_allowed")
            message = (
                "the request has no Host header (HTTP/1.1 requires one; the blimp checks it against DNS rebinding)"
                if host is None
                else f"Host {host[:80]!r} is not one of this blimp's names; add it to [http] allowed_hosts if it is"
            )
            return error_response(403, message, "host_not_allowed")
        return await handler(request)

    return host_check


def make_cors_middleware(allowed: frozenset[str]) -> Callable[..., Awaitable[web.StreamResponse]]:
    @web.middleware
    async def cors(request: web.Request, handler: Handler) -> web.StreamResponse:
        origin = request.headers.get("Origin")
        if request.method == "OPTIONS" and origin is not None and "Access-Control-Request-Method" in request.headers:
            if not origin_allowed(request, origin, allowed):
                return error_response(403, f"origin {origin[:80]} is not in [http] cors_origins", "origin_not_allowed")
            return web.Response(
                status=204,
                headers={
                    "Access-Control-Allow-Origin": origin,
                    "Access-Control-Allow-Methods": ALLOWED_METHODS,
                    "Access-Control-Allow-Headers": ALLOWED_HEADERS,
                    "Access-Control-Max-Age": "600",
                    "Vary": "Origin",
                },
            )
        if origin is not None and not origin_allowed(request, origin, allowed):
            # A foreign page must not act even with a stolen token (browsers send the Origin of every
            # cross-site fetch and WebSocket); direct clients such as the headset app send no Origin.
            return error_response(403, f"origin {origin[:80]} is not in [http] cors_origins", "origin_not_allowed")
        if origin is not None:
            request[CORS_ORIGIN] = origin
        return await handler(request)

    return cors


CORS_ORIGIN = "feelium_cors_origin"


async def add_cors_headers(request: web.Request, response: web.StreamResponse) -> None:
    """``on_response_prepare`` hook, so streamed responses (MJPEG, SSE) carry the headers too."""
    origin = request.get(CORS_ORIGIN)
    if origin is not None:
        response.headers["Access-Control-Allow-Origin"] = origin
        response.headers["Vary"] = "Origin"
        response.headers["Access-Control-Expose-Headers"] = "X-Speech-Seq, X-Frame-Seq, X-Feelium-Capture-T, Retry-After"


@web.middleware
async def require_token(request: web.Request, handler: Handler) -> web.StreamResponse:
    """401 JSON unless the request carries the token (header, or ``?token=`` for img/EventSource/WebSocket)."""
    if needs_token(request.path):
        link = ctx(request)
        if not link.tokens.matches(presented_token(request.headers, request.query, request.cookies), link.hub.clock()):
            link.count("unauthorized")
            return error_response(
                401,
                "missing or wrong token: send Authorization: Bearer <token> (or ?token= for video, SSE and WebSocket)",
                headers={"WWW-Authenticate": 'Bearer realm="feelium"'},
            )
        link.last_request_at = link.hub.clock()
    return await handler(request)
