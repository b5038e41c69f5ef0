"""Running the app: JSON bodies even for requests aiohttp's HTTP parser rejects, and logs without the token.

A malformed request line, a bad ``Content-Length`` or oversized headers never
reach the app's middlewares: aiohttp's connection handler answers them itself
with a plain-text 400. The API promises a JSON error for every bad request, so
the runner swaps in a connection handler whose ``handle_error`` (aiohttp's
documented hook for exactly these answers) returns ``{"error", "message"}``.

Whatever the server writes to its log about a request (the optional access
log, a rejected request line) goes through :func:`redact` first: a token in a
query string or an ``Authorization`` header must never reach the journal.
"""

from __future__ import annotations

import asyncio
import logging
import re
from typing import Any
from urllib.parse import parse_qsl, unquote

from aiohttp import web
from aiohttp.abc import AbstractAccessLogger
from aiohttp.web_protocol import RequestHandler
from aiohttp.web_request import BaseRequest

from feelium.http.errors import error_response

log = logging.getLogger(__name__)

MAX_MESSAGE = 300
_SECRETS = re.compile(r"(?i)(token=|bearer\s+)[^&\s'\"]+")
# A token has at least 16 characters (feelium.http.auth), so no part of a URL that long is ever logged whole,
# wherever a client put it (a path segment, a query value, under a percent-encoded key).
SECRET_MIN_CHARS = 16
_LONG_WITH_DIGIT = re.compile(r"[^\s/?&=;'\"]*[0-9_][^\s/?&=;'\"]*")


def redact(text: str) -> str:
    """Free text (a rejected request line) with its percent-escapes decoded, every ``token=...`` value and
    ``Bearer ...`` credential replaced by ``<redacted>``, and any other long run holding a digit elided."""
    text = _SECRETS.sub(lambda m: m.group(1) + "<redacted>", unquote(text))
    text = _LONG_WITH_DIGIT.sub(lambda m: m.group(0) if len(m.group(0)) < SECRET_MIN_CHARS else "<elided>", text)
    return _printable(text)


def _printable(text: str) -> str:
    """Control characters escaped (``\\x0a``): a decoded newline, CR, ESC or NUL must not forge or break log lines."""
    return "".join(c if c.isprintable() else f"\\x{ord(c):02x}" for c in text)


def _shown(part: str) -> str:
    return _printable(part) if len(part) < SECRET_MIN_CHARS else f"<{len(part)} chars>"


def loggable_target(path_qs: str) -> str:
    """A request target for the log: path segments and query keys and values decoded, the ``token`` value
    redacted, and anything of a token's length or more shown only as its length."""
    path, sep, query = path_qs.partition("?")
    shown = "/".join(_shown(unquote(segment)) for segment in path.split("/"))
    if sep:
        pairs = parse_qsl(query, keep_blank_values=True)
        shown += "?" + "&".join(
            f"{_shown(key)}={'<redacted>' if key.strip().lower() == 'token' else _shown(value)}" for key, value in pairs
        )
    return shown


class RedactingAccessLogger(AbstractAccessLogger):
    """One debug line per request: address, method, path with its query redacted, status, bytes, milliseconds.

    No headers are logged at all (so no ``Authorization``), and the target passes :func:`loggable_target`.
    """

    def log(self, request: BaseRequest, response: web.StreamResponse, time: float) -> None:
        self.logger.debug(
            "%s %s %s %d %d %.1fms",
            request.remote, request.method, loggable_target(request.raw_path), response.status, response.body_length, time * 1000.0,
        )

    @property
    def enabled(self) -> bool:
        return self.logger.isEnabledFor(logging.DEBUG)


class JsonErrorRequestHandler(RequestHandler):
    """aiohttp's connection handler with JSON bodies for the errors it answers itself."""

    __slots__ = ()  # same layout as RequestHandler, so a handler's class can be swapped in place

    def handle_error(
        self, request: BaseRequest, status: int = 500, exc: BaseException | None = None, message: str | None = None
    ) -> web.StreamResponse:
        if request.writer.output_size > 0:  # as aiohttp does: too late for an answer, drop the connection
            raise ConnectionError("a response was already under way when the request failed")
        if status >= 500:
            log.error("unexpected error in a request from %s", request.remote, exc_info=exc)
            response = error_response(status, "internal error (logged on the blimp)", "internal")
        else:
            text = (message or (str(exc) if exc is not None else "") or "malformed request").strip()
            # Anyone on the Wi-Fi can send garbage: one line per rejection, not a traceback.
            text = redact(text)  # the parser quotes the request line, query string and all
            log.info("rejected a malformed request from %s: %s", request.remote, text.splitlines()[0][:120])
            response = error_response(status, f"malformed HTTP request: {text[:MAX_MESSAGE]}")
        response.force_close()
        return response


class ConnectionLimits:
    """Open connections in total and per remote address, whatever they are doing.

    Every connection holds a file descriptor, before it has sent a request, while it long-polls, while it
    trickles a request line that never ends. Without a cap, one address opening a few thousand of them used
    up the daemon's descriptors and a bystander's `stop` could not connect; with one, a single device can
    hold at most ``per_address`` and the rest of the room still gets in.
    """

    def __init__(self, total: int, per_address: int) -> None:
        if total < 1 or per_address < 1:
            raise ValueError("connection limits must be at least 1")
        self.total = total
        self.per_address = per_address
        self._address_of: dict[int, str] = {}
        self._by_address: dict[str, int] = {}
        self.refused = 0

    def admit(self, key: int, address: str) -> bool:
        """Count connection ``key`` from ``address``; ``False`` (nothing counted) when a limit is reached."""
        if len(self._address_of) >= self.total or self._by_address.get(address, 0) >= self.per_address:
            self.refused += 1
            return False
        self._address_of[key] = address
        self._by_address[address] = self._by_address.get(address, 0) + 1
        return True

    def release(self, key: int) -> None:
        address = self._address_of.pop(key, None)
        if address is not None:
            left = self._by_address[address] - 1
            if left:
                self._by_address[address] = left
            else:
                del self._by_address[address]

    def __len__(self) -> int:
        return len(self._address_of)


class _JsonErrorServer(web.Server):
    """The connection factory: every new connection gets a :class:`JsonErrorRequestHandler`, within the
    runner's :class:`ConnectionLimits` (a connection over them is closed at once, before it is read)."""

    connection_limits: ConnectionLimits | None

    def __call__(self) -> RequestHandler:
        handler = super().__call__()
        handler.__class__ = JsonErrorRequestHandler
        return handler

    def connection_made(self, handler: RequestHandler, transport: asyncio.Transport) -> None:
        super().connection_made(handler, transport)
        limits = self.connection_limits
        peer = transport.get_extra_info("peername")
        address = str(peer[0]) if isinstance(peer, tuple) and peer else "local"
        if limits is not None and not limits.admit(id(handler), address):
            transport.abort()

    def connection_lost(self, handler: RequestHandler, exc: BaseException | None = None) -> None:
        super().connection_lost(handler, exc)
        if self.connection_limits is not None:
            self.connection_limits.release(id(handler))


class JsonErrorAppRunner(web.AppRunner):
    """``web.AppRunner`` whose connections answer parser-level errors in JSON too, within ``connection_limits``."""

    def __init__(self, app: web.Application, *, connection_limits: ConnectionLimits | None = None, **kwargs: Any) -> None:
        super().__init__(app, **kwargs)
        self.connection_limits = connection_limits

    async def _make_server(self) -> web.Server:
        server = await super()._make_server()
        server.__class__ = _JsonErrorServer
        server.connection_limits = self.connection_limits  # type: ignore[attr-defined]
        return server
