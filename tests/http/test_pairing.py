"""Pairing codes (valid once, expiring, void after repeated guesses) and token rotation without a restart."""

from __future__ import annotations

import asyncio
import contextlib
import re
from dataclasses import replace
from pathlib import Path

import aiohttp
import pytest

from feelium.http.app import create_app
from feelium.http.auth import TokenError, TokenStore, load_or_create_token, write_new_token
from feelium.http.pairing import PairingCodes

from tests.http.http_support import AUTH, TOKEN


def test_a_code_works_once_and_only_before_it_expires() -> None:
    codes = PairingCodes(ttl_s=120.0)
    code = codes.issue(now=1000.0)
    assert len(code) == 9 and code[4] == "-"
    assert codes.redeem(code.replace("-", " "), now=1119.9)  # typed with a space: the same digits
    assert not codes.redeem(code, now=1120.0)  # used up
    code = codes.issue(now=2000.0)
    assert codes.remaining_s(2030.0) == pytest.approx(90.0)
    assert not codes.redeem(code, now=2120.0)  # expired
    assert codes.remaining_s(2120.0) is None


def test_a_new_code_replaces_the_old_and_guessing_voids_it() -> None:
    codes = PairingCodes(ttl_s=60.0, max_failures=5)
    old = codes.issue(0.0)
    new = codes.issue(1.0)
    assert old == new or not codes.redeem(old, 2.0)  # (1 in 10^8 they are equal)
    code = codes.issue(3.0)
    wrong = "0000-0000" if code != "0000-0000" else "1111-1111"
    for _ in range(5):
        assert not codes.redeem(wrong, 4.0)
    assert not codes.redeem(code, 5.0)  # five wrong guesses made the right code worthless
    assert codes.refused >= 6 and codes.paired == 0


async def test_pairing_exchanges_a_code_for_the_token_once(client, clock) -> None:  # type: ignore[no-untyped-def]
    assert (await client.post("/api/v1/pair/code")).status == 401  # only a holder of the token makes codes
    resp = await client.post("/api/v1/pair/code", headers=AUTH)
    body = await resp.json()
    assert resp.status == 200 and body["expires_in_s"] == 120.0
    got = await client.post("/api/v1/pair", json={"code": body["code"]})
    assert got.status == 200 and await got.json() == {"token": TOKEN}
    again = await client.post("/api/v1/pair", json={"code": body["code"]})
    assert again.status == 403 and (await again.json())["error"] == "pairing_failed"
    code = (await (await client.post("/api/v1/pair/code", headers=AUTH)).json())["code"]
    clock.now += 121.0
    assert (await client.post("/api/v1/pair", json={"code": code})).status == 403
    assert (await client.post("/api/v1/pair", json={"code": 12345678})).status == 400


def test_the_store_notices_a_rotated_file_within_its_check_interval(tmp_path: Path) -> None:
    path = tmp_path / "token"
    first = load_or_create_token("", str(path))
    store = TokenStore(first, str(path), check_every_s=1.0)
    assert store.matches(first, 10.0)
    second = write_new_token(str(path))  # what `feelium token rotate` does
    assert path.stat().st_mode & 0o777 == 0o600
    assert store.matches(first, 10.5)  # not looked at again yet
    assert store.matches(second, 11.0) and not store.matches(first, 11.0)
    path.write_text("short\n")  # a broken file keeps the last good token
    assert store.matches(second, 12.0)
    with pytest.raises(ValueError, match=r"\[http\] token"):
        TokenStore(TOKEN, None).rotate()


async def test_rotation_by_api_and_by_file_without_a_restart(aiohttp_client, hub, clock, http_config, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "token"
    config = replace(http_config, token="", token_file=str(path))
    old = load_or_create_token("", str(path))
    client = await aiohttp_client(create_app(config, hub, old))
    bearer = lambda t: {"Authorization": f"Bearer {t}"}  # noqa: E731
    resp = await client.post("/api/v1/token/rotate", headers=bearer(old))
    new = (await resp.json())["token"]
    assert resp.status == 200 and new != old and path.read_text().strip() == new
    assert (await client.get("/api/v1/state", headers=bearer(old))).status == 401
    assert (await client.get("/api/v1/state", headers=bearer(new))).status == 200
    newer = write_new_token(str(path))  # `feelium token rotate` in another process
    clock.now += 1.0
    assert (await client.get("/api/v1/state", headers=bearer(new))).status == 401
    assert (await client.get("/api/v1/state", headers=bearer(newer))).status == 200


async def test_rotating_the_token_ends_the_streams_opened_with_the_old_one(aiohttp_client, hub, http_config, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A device whose token was rotated away must not keep steering, watching or listening over sockets it
    already holds: within about a second each of them is closed, and the new token opens them again."""
    import numpy as np
    from aiohttp import WSMsgType

    path = tmp_path / "token"
    config = replace(http_config, token="", token_file=str(path))
    old = load_or_create_token("", str(path))
    client = await aiohttp_client(create_app(config, hub, old))
    bearer = lambda t: {"Authorization": f"Bearer {t}"}  # noqa: E731
    hub.front_video.publish(1.0, np.zeros((8, 8), np.uint8))
    events = await client.ws_connect("/api/v1/events/ws", headers=bearer(old))
    speech = await client.ws_connect("/api/v1/speech/stream", headers=bearer(old))
    video = await client.get("/api/v1/video/front.mjpeg", headers=bearer(old))
    assert video.status == 200

    async def watch() -> None:  # a reader that keeps up, so only the rotation can end its stream
        while await video.content.read(65536):
            pass

    watching = asyncio.create_task(watch())
    await asyncio.sleep(0.5)
    from feelium.http.app import link_of

    assert not watching.done() and len(link_of(client.server.app).open_streams) == 3
    resp = await client.post("/api/v1/token/rotate", headers=bearer(old))
    new = (await resp.json())["token"]
    # 1008 "token rotated", or a reset when the client's own close reply finds the socket gone already
    assert await asyncio.wait_for(_until_closed(events, WSMsgType), 5) in (1008, "reset")
    assert await asyncio.wait_for(_until_closed(speech, WSMsgType), 5) in (1008, "reset")
    with contextlib.suppress(aiohttp.ClientError):  # the MJPEG response is cut off
        await asyncio.wait_for(watching, 5)
    streams = link_of(client.server.app).open_streams
    assert len(streams) == 0 and streams.closed_for_rotation >= 2  # (a cut stream may end on its own error first)
    fresh = await client.ws_connect("/api/v1/events/ws", headers=bearer(new))
    assert not fresh.closed
    await fresh.close()


async def _until_closed(ws, kinds) -> int | str | None:  # type: ignore[no-untyped-def]
    """The close code the server sent, or "reset" (the client's own close reply found the socket gone already)."""
    while True:
        try:
            msg = await ws.receive()
        except aiohttp.ClientConnectionResetError:
            return "reset"
        if msg.type in (kinds.CLOSE, kinds.CLOSED, kinds.CLOSING, kinds.ERROR):
            return msg.data if msg.type == kinds.CLOSE else ws.close_code


async def test_a_configured_token_cannot_be_rotated_by_api(client) -> None:  # type: ignore[no-untyped-def]
    resp = await client.post("/api/v1/token/rotate", headers=AUTH)
    assert resp.status == 409 and (await resp.json())["error"] == "token_not_rotatable"


async def test_feelium_pair_and_token_rotate_against_a_running_daemon(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from feelium.cli import main
    from feelium.daemon.assembly import build_http
    from feelium.daemon.config import Config
    from feelium.http.config import HttpConfig
    from feelium.hub import Hub

    token_file = tmp_path / "token"
    service = build_http(replace(Config(), http=replace(HttpConfig(), host="127.0.0.1", port=0, token_file=str(token_file))), Hub())
    task = asyncio.create_task(service.run())  # type: ignore[union-attr]
    try:
        while not service.port:  # type: ignore[union-attr]
            await asyncio.sleep(0.01)
        config = tmp_path / "feelium.toml"
        config.write_text(f'[http]\nport = {service.port}\ntoken_file = "{token_file}"\n')  # type: ignore[union-attr]
        assert await asyncio.to_thread(main, ["pair", "--config", str(config)]) == 0
        out = capsys.readouterr().out
        match = re.search(r"pairing code: (\d{4}-\d{4})", out)
        assert match and f"http://127.0.0.1:{service.port}/" in out and "token=" not in out  # type: ignore[union-attr]
        base = f"http://127.0.0.1:{service.port}/api/v1"  # type: ignore[union-attr]
        async with aiohttp.ClientSession() as session:
            async with session.post(f"{base}/pair", json={"code": match.group(1)}) as resp:
                assert resp.status == 200 and (await resp.json())["token"] == token_file.read_text().strip()
            old = token_file.read_text().strip()
            assert await asyncio.to_thread(main, ["token", "rotate", "--config", str(config)]) == 0
            new = token_file.read_text().strip()
            assert new != old
            deadline = asyncio.get_running_loop().time() + 5.0
            while True:  # the daemon looks at the file at most once a second
                async with session.get(f"{base}/state", headers={"Authorization": f"Bearer {new}"}) as resp:
                    if resp.status == 200:
                        break
                assert asyncio.get_running_loop().time() < deadline, "the daemon never took the rotated token"
                await asyncio.sleep(0.1)
            async with session.get(f"{base}/state", headers={"Authorization": f"Bearer {old}"}) as resp:
                assert resp.status == 401
        health = service.health()  # type: ignore[union-attr]
        assert health["pairings"] == 1 and health["token_rotations"] == 1
    finally:
        await service.stop()  # type: ignore[union-attr]
        await asyncio.wait_for(task, 5)


async def test_a_browser_session_cookie_replaces_the_token_in_urls(client) -> None:  # type: ignore[no-untyped-def]
    assert (await client.post("/api/v1/session")).status == 401
    resp = await client.post("/api/v1/session", headers=AUTH)
    assert resp.status == 204
    cookie = resp.cookies["feelium_token"]
    assert cookie.value == TOKEN and cookie["httponly"] and cookie["samesite"] == "Strict" and cookie["path"] == "/api/v1"
    # the test client's cookie jar now sends it, as a browser would for <img> and EventSource: no header, no ?token=
    assert (await client.get("/api/v1/state")).status == 200
    ws = await client.ws_connect("/api/v1/events/ws")
    await ws.close()


def test_a_token_file_whose_folder_cannot_be_made_names_the_file_and_the_key(tmp_path):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    with pytest.raises(TokenError, match=r"token\.txt: cannot create the token file \(\[http\] token_file\)"):
        load_or_create_token("", str(blocker / "sub" / "token.txt"))
