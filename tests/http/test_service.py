"""The headset link as a daemon service on a real loopback socket: parser-level errors in JSON, TLS from files."""

from __future__ import annotations

import asyncio
import hashlib
import json
import logging
import shutil
import socket
import ssl
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import aiohttp
import pytest

from feelium.daemon.config import Config
from feelium.http.config import HttpConfig
from feelium.daemon.assembly import build_http
from feelium.http.service import HttpService, client_urls, tls_context
from feelium.settings import ConfigError
from feelium.hub import Hub

from tests.http.http_support import AUTH, TOKEN


async def _started(config: HttpConfig) -> tuple[HttpService, asyncio.Task[None]]:
    service = build_http(replace(Config(), http=config), Hub())
    assert isinstance(service, HttpService)
    task = asyncio.create_task(service.run())
    for _ in range(200):
        if service.port:
            return service, task
        await asyncio.sleep(0.01)
    raise AssertionError("the service did not start listening")


async def _stopped(service: HttpService, task: asyncio.Task[None]) -> None:
    await service.stop()
    await asyncio.wait_for(task, 5)


def _loopback(**changes: object) -> HttpConfig:
    return replace(HttpConfig(), host="127.0.0.1", port=0, token=TOKEN, **changes)


async def _raw(port: int, request: bytes) -> bytes:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(request)
    await writer.drain()
    data = await asyncio.wait_for(reader.read(), 5)
    writer.close()
    return data


@pytest.mark.parametrize(
    "request_bytes",
    [
        b"GARBAGE\r\n\r\n",
        b"GET /api/v1/state HTTP/1.1\r\nHost: x\r\nContent-Length: abc\r\n\r\n",
        b"GET /api/v1/state HTTP/1.1\r\nHost: x\r\nX-Long: " + b"a" * 20000 + b"\r\n\r\n",
        b"POST /api/v1/motion HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\nContent-Length: 3\r\n\r\n",
    ],
    ids=["request-line", "content-length", "header-too-long", "length-and-chunked"],
)
async def test_requests_the_http_parser_rejects_get_a_json_400(request_bytes: bytes) -> None:
    service, task = await _started(_loopback())
    try:
        answer = await _raw(service.port, request_bytes)  # type: ignore[arg-type]
    finally:
        await _stopped(service, task)
    head, _, body = answer.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.") and b" 400 " in head.split(b"\r\n")[0]
    assert b"application/json" in head
    error = json.loads(body)
    assert error["error"] == "bad_request" and error["message"].startswith("malformed HTTP request")


def _self_signed(tmp: Path) -> tuple[Path, Path]:
    cert, key = tmp / "cert.pem", tmp / "key.pem"
    subprocess.run(
        ["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-days", "1", "-subj", "/CN=127.0.0.1",
         "-addext", "subjectAltName=IP:127.0.0.1", "-keyout", str(key), "-out", str(cert)],
        check=True, capture_output=True, timeout=60,
    )  # fmt: skip
    return cert, key


@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl command to make a test certificate")
async def test_tls_from_configured_files_serves_https_only(tmp_path: Path) -> None:
    cert, key = _self_signed(tmp_path)
    config = _loopback(tls_cert=str(cert), tls_key=str(key))
    service, task = await _started(config)
    trust = ssl.create_default_context(cafile=str(cert))
    try:
        base = f"https://127.0.0.1:{service.port}/api/v1"
        async with aiohttp.ClientSession() as session:
            async with session.get(f"{base}/health", ssl=trust) as resp:
                assert resp.status == 200
            async with session.get(f"{base}/state", ssl=trust) as resp:
                assert resp.status == 401
            async with session.get(f"{base}/state", ssl=trust, headers=AUTH) as resp:
                assert resp.status == 200 and "services" in await resp.json()
            with pytest.raises(aiohttp.ClientError):  # plain HTTP is not spoken on the TLS port
                async with session.get(f"http://127.0.0.1:{service.port}/api/v1/health") as resp:
                    await resp.read()
    finally:
        await _stopped(service, task)
    assert client_urls(config, 8443, TOKEN) == [f"https://127.0.0.1:8443/#token={TOKEN}"]


def test_tls_needs_both_files_and_a_bad_pair_fails_at_build_time(tmp_path: Path) -> None:
    assert tls_context(_loopback()) is None
    with pytest.raises(ConfigError, match="tls_key: tls_cert and tls_key must be set together"):
        tls_context(_loopback(tls_cert=str(tmp_path / "cert.pem")))
    with pytest.raises(ConfigError, match=r"tls_cert: cannot read .*cert.pem: No such file"):
        tls_context(_loopback(tls_cert=str(tmp_path / "cert.pem"), tls_key=str(tmp_path / "key.pem")))
    (tmp_path / "cert.pem").write_text("not a certificate")
    (tmp_path / "key.pem").write_text("not a key")
    with pytest.raises(ConfigError, match="are not a PEM certificate and its key"):
        tls_context(_loopback(tls_cert=str(tmp_path / "cert.pem"), tls_key=str(tmp_path / "key.pem")))


def test_a_tls_misconfiguration_stops_the_daemon_with_one_line(tmp_path: Path) -> None:
    """Before, build_services logged the failure and the daemon ran on without the API."""
    from feelium.daemon.assembly import SERVICES, build_services

    bad = _loopback(tls_cert=str(tmp_path / "missing.pem"), tls_key=str(tmp_path / "missing.key"))
    with pytest.raises(ConfigError, match="missing.pem"):
        build_services(replace(Config(), http=bad), Hub(), tuple(b for b in SERVICES if b[0] == "http"))
    config = tmp_path / "feelium.toml"
    config.write_text(f'[http]\nport = 0\ntoken = "{TOKEN}"\ntls_cert = "{tmp_path}/missing.pem"\ntls_key = "{tmp_path}/k.pem"\n')
    done = subprocess.run(
        [sys.executable, "-m", "feelium", "run", "--sim", "--config", str(config)],
        capture_output=True, text=True, timeout=120, cwd=Path(__file__).resolve().parents[2], check=False,
    )
    errors = [line for line in done.stderr.splitlines() if "no projector calibration" not in line]  # an info line
    assert done.returncode == 1
    assert errors == [f"feelium: config error: [http]: tls_cert: cannot read {tmp_path}/missing.pem: No such file or directory"]


def test_disabled_link_builds_no_service_and_a_generated_token_is_private(tmp_path: Path) -> None:
    assert build_http(replace(Config(), http=replace(HttpConfig(), enabled=False)), Hub()) is None
    token_file = tmp_path / "sub" / "token"
    service = build_http(replace(Config(), http=replace(HttpConfig(), token_file=str(token_file))), Hub())
    assert token_file.stat().st_mode & 0o777 == 0o600
    assert service.token == token_file.read_text().strip() and len(service.token) >= 16  # type: ignore[attr-defined]


async def test_the_token_never_reaches_the_log(caplog: pytest.LogCaptureFixture) -> None:
    """Access log on, at debug: query tokens are redacted, headers are not logged, a rejected request line too."""
    caplog.set_level(logging.DEBUG)
    service, task = await _started(_loopback(access_log=True))
    try:
        base = f"http://127.0.0.1:{service.port}/api/v1"
        async with aiohttp.ClientSession() as session:
            async with session.get(f"{base}/state?token={TOKEN}&client=a") as resp:
                assert resp.status == 200
            async with session.get(f"{base}/state", headers=AUTH) as resp:
                assert resp.status == 200
        await _raw(service.port, f"GET /api/v1/state?token={TOKEN} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: x\r\n\r\n".encode())
    finally:
        await _stopped(service, task)
    access = [r.getMessage() for r in caplog.records if r.name == "feelium.http.access"]
    assert any("/api/v1/state?token=<redacted>&client=a 200" in line for line in access), access
    assert len(access) >= 2
    assert TOKEN not in caplog.text
    assert any("rejected a malformed request" in r.getMessage() for r in caplog.records)
    assert any(r.getMessage().startswith(f"headset client at http://127.0.0.1:{service.port}/ ") for r in caplog.records)


def test_redact_hides_every_form_of_the_token() -> None:
    from feelium.http.server import redact

    assert redact("GET /x?a=1&token=s3cr3t&b=2 HTTP/1.1") == "GET /x?a=1&token=<redacted>&b=2 HTTP/1.1"
    assert redact("Authorization: Bearer s3cr3t") == "Authorization: Bearer <redacted>"
    assert redact("b'GET /x?TOKEN=s3cr3t'") == "b'GET /x?TOKEN=<redacted>'"
    assert redact(f"GET /x?to%6ben={TOKEN} HTTP/1.1") == "GET /x?token=<redacted> HTTP/1.1"  # an encoded key
    assert TOKEN not in redact(f"GET /api/v1/nothing/{TOKEN} HTTP/1.1")  # a token anywhere else
    assert redact("GET /api/v1/state HTTP/1.1: Invalid Content-Length") == "GET /api/v1/state HTTP/1.1: Invalid Content-Length"


@pytest.mark.parametrize(
    "target, logged",
    [
        (f"/api/v1/state?token={TOKEN}&client=a", "/api/v1/state?token=<redacted>&client=a"),
        (f"/api/v1/state?to%6ben={TOKEN}", "/api/v1/state?token=<redacted>"),  # the key decoded, as auth decodes it
        (f"/api/v1/state?%54OKEN={TOKEN}", "/api/v1/state?TOKEN=<redacted>"),
        (f"/api/v1/nothing/{TOKEN}", f"/api/v1/nothing/<{len(TOKEN)} chars>"),  # a 404 with the token in its path
        (f"/api/v1/events?after=12&note={TOKEN}", f"/api/v1/events?after=12&note=<{len(TOKEN)} chars>"),
        ("/api/v1/video/front.mjpeg?fps=10", "/api/v1/video/front.mjpeg?fps=10"),
        ("/api/v1/a%0aFAKE%20ERROR%20x", "/api/v1/a\\x0aFAKE ERROR x"),  # no forged log line
        ("/api/v1/events?after=1%0d%0aX%1b%5b31m%00", "/api/v1/events?after=1\\x0d\\x0aX\\x1b[31m\\x00"),
    ],
)
def test_the_access_log_target_never_carries_a_token(target: str, logged: str) -> None:
    from feelium.http.server import loggable_target

    assert loggable_target(target) == logged


@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl command to make a test certificate")
async def test_feelium_pair_prints_the_pin_openssl_gives_and_refuses_a_stale_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The fingerprint `feelium pair` prints is the SHA-256 of the DER certificate (as docs/visionos.md computes it
    with openssl) and the one the running daemon serves; a certificate file replaced under a running daemon is
    refused, since pinning it would lock the headset out of the daemon still serving the old one."""
    from feelium.cli import main

    cert, key = _self_signed(tmp_path)
    der = subprocess.run(["openssl", "x509", "-in", str(cert), "-outform", "der"], check=True, capture_output=True).stdout
    expected = ":".join(f"{b:02X}" for b in hashlib.sha256(der).digest())
    service, task = await _started(_loopback(tls_cert=str(cert), tls_key=str(key)))
    try:
        config = tmp_path / "feelium.toml"
        config.write_text(f'[http]\nport = {service.port}\ntoken = "{TOKEN}"\ntls_cert = "{cert}"\ntls_key = "{key}"\n')
        assert await asyncio.to_thread(main, ["pair", "--config", str(config)]) == 0
        out = capsys.readouterr().out
        assert f"certificate SHA-256 (pin it in the headset app): {expected}" in out and "pairing code:" in out
        other = tmp_path / "other"
        other.mkdir()
        cert.write_bytes(_self_signed(other)[0].read_bytes())  # replaced on disk, the daemon not restarted
        assert await asyncio.to_thread(main, ["pair", "--config", str(config)]) == 1
        assert "serves another certificate" in capsys.readouterr().err
    finally:
        await _stopped(service, task)


async def test_a_taken_port_reads_failed_or_starting_never_ok_between_restarts(caplog: pytest.LogCaptureFixture) -> None:
    """The http service restarted into a port another process holds crashes at each bind: its health must not
    say ok in between (a review saw ``http: ok (was failed)`` while the daemon had no headset link)."""
    from feelium.daemon.config import DaemonConfig
    from feelium.daemon.supervisor import Supervisor

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        service = build_http(replace(Config(), http=replace(_loopback(), port=port)), Hub())
        assert service is not None and service.health()["condition"] == "starting"
        fast = DaemonConfig(restart_initial_s=0.01, restart_max_s=0.05, stop_timeout_s=0.2, shutdown_budget_s=1.0)
        supervisor = Supervisor([service], fast)
        supervisor.start()
        states = set()
        try:
            for _ in range(60):
                await asyncio.sleep(0.01)
                states.add(supervisor.report()["services"]["http"]["state"])
        finally:
            await supervisor.shutdown()
    assert supervisor.records["http"].crashes >= 2
    assert "ok" not in states and "failed" in states, states
    assert "http: ok" not in caplog.text


async def test_one_address_cannot_hold_every_connection_and_a_stop_still_gets_in() -> None:
    """Connections that never finish a request each hold a descriptor: past max_connections_per_address from one
    address more are closed at once, and another client's stop is served (a review exhausted 4,096 descriptors)."""
    service, task = await _started(_loopback(max_connections=64, max_connections_per_address=8))
    port = service.port
    hogs = []
    try:
        for _ in range(12):  # half a request line each, never finished
            reader, writer = await asyncio.open_connection("127.0.0.1", port)
            writer.write(b"GET /api/v1/state HTTP/1.1\r\nHost: x\r\n")
            hogs.append((reader, writer))
        await asyncio.sleep(0.2)

        async def closed_by_server(reader: asyncio.StreamReader) -> bool:
            try:
                return await asyncio.wait_for(reader.read(1), 0.5) == b""
            except ConnectionError:
                return True
            except asyncio.TimeoutError:
                return False  # still open, waiting for the rest of its request

        refused = [r for r, _ in hogs if await closed_by_server(r)]
        assert len(refused) == 12 - 8 and service.connection_limits.refused == 4
        assert service.health()["connections"] == 8
    finally:
        for _, writer in hogs:
            writer.close()
    await asyncio.sleep(0.2)
    async with aiohttp.ClientSession() as session:  # the hogs gone, the address is served again
        async with session.post(f"http://127.0.0.1:{port}/api/v1/motion", json={"command": "stop"}, headers=AUTH) as resp:
            assert resp.status == 200
    await _stopped(service, task)
