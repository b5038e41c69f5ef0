"""Running the app so that even requests aiohttp's HTTP parser rejects get a JSON error body.

A malformed request line, a bad ``Content-Length`` or oversized headers never
reach the app's middlewares: aiohttp's connection handler answers them itself
with a plain-text 400. The API promises a JSON error for every bad request, so
the runner swaps in a connection handler whose ``handle_error`` (aiohttp's
documented hook for exactly these answers) returns ``{"error", "message"}``.
"""

from __future__ import annotations

import logging

from aiohttp import web
from aiohttp.web_protocol import RequestHandler
from aiohttp.web_request import BaseRequest

from feelium.http.errors import error_response

log = logging.getLogger(__name__)

MAX_MESSAGE = 300


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
            log.info("rejected a malformed request from %s: %s", request.remote, text.splitlines()[0][:120])
            response = error_response(status, f"malformed HTTP request: {text[:MAX_MESSAGE]}")
        response.force_close()
        return response


class _JsonErrorServer(web.Server):
    """The connection factory: every new connection gets a :class:`JsonErrorRequestHandler`."""

    def __call__(self) -> RequestHandler:
        handler = super().__call__()
        handler.__class__ = JsonErrorRequestHandler
        return handler


class JsonErrorAppRunner(web.AppRunner):
    """``web.AppRunner`` whose connections answer parser-level errors in JSON too."""

    async def _make_server(self) -> web.Server:
        server = await super()._make_server()
        server.__class__ = _JsonErrorServer
        return server
