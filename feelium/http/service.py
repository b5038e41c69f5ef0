"""The headset link as a daemon service: serves the API and the browser client on the configured port."""

from __future__ import annotations

import asyncio
import logging
import socket
import ssl
from pathlib import Path
from typing import Any

from aiohttp import web

from feelium.http.addresses import interface_ipv4, reachable_hosts, url_host
from feelium.http.app import link_of
from feelium.http.config import HttpConfig
from feelium.http.server import ConnectionLimits, JsonErrorAppRunner, RedactingAccessLogger
from feelium.hub import Hub
from feelium.settings import ConfigError

log = logging.getLogger(__name__)


def tls_context(config: HttpConfig) -> ssl.SSLContext | None:
    """An HTTPS context from the configured files, or ``None`` when neither is set.

    Anything else wrong (one file set without the other, a missing or unreadable file, not a matching PEM
    pair) is a :class:`ConfigError`: the daemon stops with that one line instead of running without the API
    the headset was promised.
    """
    if not config.tls_cert and not config.tls_key:
        return None
    if not (config.tls_cert and config.tls_key):
        missing = "tls_key" if config.tls_cert else "tls_cert"
        raise ConfigError("[http]", missing, "tls_cert and tls_key must be set together")
    for key, name in (("tls_cert", config.tls_cert), ("tls_key", config.tls_key)):
        path = Path(name).expanduser()
        try:
            with path.open("rb"):
                pass
        except OSError as exc:
            raise ConfigError("[http]", key, f"cannot read {path}: {exc.strerror}") from None
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    try:
        context.load_cert_chain(Path(config.tls_cert).expanduser(), Path(config.tls_key).expanduser())
    except ssl.SSLError as exc:
        raise ConfigError(
            "[http]", "tls_cert", f"{config.tls_cert} and {config.tls_key} are not a PEM certificate and its key: {exc.reason or exc}"
        ) from None
    return context


def client_urls(config: HttpConfig, port: int | None = None, token: str | None = None) -> list[str]:
    """Every address the browser client can be opened at; with ``token``, it rides in the URL fragment.

    The fragment never travels to the server or a proxy; it is only for a person's own terminal (``feelium
    http-url``), never for the log.
    """
    scheme = "https" if config.tls_cert else "http"
    hosts = reachable_hosts(config.host, interface_ipv4(), socket.gethostname())
    fragment = f"#token={token}" if token else ""
    return [f"{scheme}://{url_host(h)}:{port if port is not None else config.port}/{fragment}" for h in hosts]


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
        self.listening = False  # only once the socket is bound does the headset have a link
        self.connection_limits: ConnectionLimits | None = None
        self._runner: web.AppRunner | None = None
        self._stopped = asyncio.Event()

    async def run(self) -> None:
        self._stopped = asyncio.Event()
        access = logging.getLogger("feelium.http.access") if self.config.access_log else None
        limits = ConnectionLimits(self.config.max_connections, self.config.max_connections_per_address)
        self.connection_limits = limits
        runner = JsonErrorAppRunner(self.app, access_log=access, access_log_class=RedactingAccessLogger, shutdown_timeout=0.2,
                                    connection_limits=limits)  # fmt: skip
        await runner.setup()
        self._runner = runner
        try:
            site = web.TCPSite(runner, self.config.host, self.config.port, ssl_context=tls_context(self.config))
            await site.start()
            server = getattr(site, "_server", None)
            sockets = getattr(server, "sockets", None) or []
            self.port = sockets[0].getsockname()[1] if sockets else self.config.port
            self.listening = True
            urls = client_urls(self.config, self.port)
            log.info("headset client at %s (the token: feelium http-url, or pair with feelium pair)", ", ".join(urls))
            await self._stopped.wait()
        finally:
            self.listening = False
            self._runner = None
            await runner.cleanup()

    async def stop(self) -> None:
        self._stopped.set()

    def health(self) -> dict[str, Any]:
        """The link's counters; ``starting`` until the socket is bound, so a restart that cannot bind (port taken)
        never reads ok between its crashes."""
        link = link_of(self.app)
        listening = {} if self.listening else {"condition": "starting", "reason": f"not listening on {self.config.host}:{self.config.port} yet"}
        return listening | {
            "port": self.port,
            "connections": len(self.connection_limits) if self.connection_limits is not None else 0,
            "connections_refused": self.connection_limits.refused if self.connection_limits is not None else 0,
            "last_seq": link.events.ring.last_seq,
            "motion_rate_limited": link.motion_limit.rejected,
            "action_rate_limited": link.action_limit.rejected,
            "speech_rate_limited": link.speech_limit.rejected,
            "motion_refused_not_in_control": link.lease.refused,
            "motion_takeovers": link.lease.takeovers,
            "video_streams_refused": link.streams.refused,
            "speech_streams_refused": link.speech_streams.refused,
            "pairings": link.pairing.paired,
            "pairing_refused": link.pairing.refused,
            "token_rotations": link.tokens.rotations,
            **{f"video_{name}": feed.health() for name, feed in link.videos.items()},
            **link.counters,
            **{f"events_{k}": v for k, v in link.events.health().items()},
        }
