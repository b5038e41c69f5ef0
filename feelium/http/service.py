"""The headset link as a daemon service: serves the API and the browser client on the configured port."""

from __future__ import annotations

import asyncio
import logging
import ssl
from typing import Any

from aiohttp import web

from feelium.http.app import link_of
from feelium.http.config import HttpConfig
from feelium.http.server import JsonErrorAppRunner
from feelium.hub import Hub

log = logging.getLogger(__name__)


def tls_context(config: HttpConfig) -> ssl.SSLContext | None:
    """An HTTPS context from the configured files, or ``None``; a half-configured pair is an error."""
    if not config.tls_cert and not config.tls_key:
        return None
    if not (config.tls_cert and config.tls_key):
        raise ValueError("[http] tls_cert and tls_key must be set together")
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    context.load_cert_chain(config.tls_cert, config.tls_key)
    return context


def client_url(config: HttpConfig, token: str, port: int | None = None) -> str:
    """The browser client's address with the token in the fragment (never sent to servers or logs of proxies)."""
    scheme = "https" if config.tls_cert else "http"
    host = "127.0.0.1" if config.host in ("0.0.0.0", "::", "") else config.host
    return f"{scheme}://{host}:{port if port is not None else config.port}/#token={token}"


class HttpService:
    """Runs the aiohttp app until stopped."""

    name = "http"
    stop_order = 90  # last: the headset should see the blimp stop before the link goes

    def __init__(self, config: HttpConfig, hub: Hub, token: str, app: web.Application) -> None:
        self.config = config
        self.hub = hub
        self.token = token
        self.app = app
        self.port: int | None = None
        self._runner: web.AppRunner | None = None
        self._stopped = asyncio.Event()

    async def run(self) -> None:
        self._stopped = asyncio.Event()
        runner = JsonErrorAppRunner(self.app, access_log=None, shutdown_timeout=0.2)
        await runner.setup()
        self._runner = runner
        try:
            site = web.TCPSite(runner, self.config.host, self.config.port, ssl_context=tls_context(self.config))
            await site.start()
            server = getattr(site, "_server", None)
            sockets = getattr(server, "sockets", None) or []
            self.port = sockets[0].getsockname()[1] if sockets else self.config.port
            log.info("headset client: %s", client_url(self.config, self.token, self.port))
            await self._stopped.wait()
        finally:
            self._runner = None
            await runner.cleanup()

    async def stop(self) -> None:
        self._stopped.set()

    def health(self) -> dict[str, Any]:
        link = link_of(self.app)
        return {
            "port": self.port,
            "last_seq": link.events.ring.last_seq,
            "motion_rate_limited": link.motion_limit.rejected,
            "action_rate_limited": link.action_limit.rejected,
            "speech_rate_limited": link.speech_limit.rejected,
            "motion_refused_not_in_control": link.lease.refused,
            "motion_takeovers": link.lease.takeovers,
            "video_streams_refused": link.streams.refused,
            **{f"video_{name}": feed.health() for name, feed in link.videos.items()},
            **link.counters,
            **{f"events_{k}": v for k, v in link.events.health().items()},
        }
