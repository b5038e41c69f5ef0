"""Pairing, the browser's session cookie and token rotation: thin handlers over :class:`PairingCodes` and
:class:`TokenStore`."""

from __future__ import annotations

from aiohttp import web

from feelium.http.auth import SESSION_COOKIE, TokenError
from feelium.http.clients import client_of
from feelium.http.context import ctx
from feelium.http.ratelimit import charge
from feelium.http.errors import ApiError
from feelium.http.params import check_keys, read_json_object

MAX_CODE = 32


async def post_pair_code(request: web.Request) -> web.Response:
    """A new pairing code (needs the token: ``feelium pair`` asks on the wearer's behalf); replaces the last one."""
    link = ctx(request)
    now = link.hub.clock()
    code = link.pairing.issue(now)
    link.count("pairing_codes")
    return web.json_response({"code": code, "expires_in_s": link.pairing.ttl_s}, headers={"Cache-Control": "no-store"})


async def post_pair(request: web.Request) -> web.Response:
    """``{"code": "1234-5678"}`` -> ``{"token": ...}``, once per code, within its lifetime (no token needed)."""
    link = ctx(request)
    body = await read_json_object(request, link.config.max_json_bytes, link.config.max_json_depth)
    check_keys(body, {"code"})
    code = body.get("code")
    if not isinstance(code, str) or not 1 <= len(code) <= MAX_CODE:
        raise ApiError(400, f"code must be a string of 1..{MAX_CODE} characters, as feelium pair printed it")
    now = link.hub.clock()
    charge(link.action_limit, client_of(request), now, "pairing attempts")
    if not link.pairing.redeem(code, now):
        raise ApiError(403, "wrong, used or expired pairing code: run feelium pair for a new one", "pairing_failed")
    return web.json_response({"token": link.tokens.current(now)}, headers={"Cache-Control": "no-store"})


async def post_token_rotate(request: web.Request) -> web.Response:
    """A new token in force at once (the old one, which authorised this request, stops working)."""
    link = ctx(request)
    try:
        token = link.tokens.rotate()
    except TokenError as exc:
        raise ApiError(409, str(exc), "token_not_rotatable") from exc
    return web.json_response({"token": token}, headers={"Cache-Control": "no-store"})


async def post_session(request: web.Request) -> web.Response:
    """Give a browser page the token as a cookie, so ``<img>``, ``EventSource`` and ``WebSocket`` need no ``?token=``.

    HttpOnly (page scripts cannot read it back), SameSite=Strict (no other site's page makes the browser send it),
    scoped to the API and, over HTTPS, Secure. It lasts until the browser closes or the token rotates.
    """
    link = ctx(request)
    response = web.Response(status=204, headers={"Cache-Control": "no-store"})
    response.set_cookie(
        SESSION_COOKIE, link.tokens.current(link.hub.clock()), path="/api/v1", httponly=True, samesite="Strict",
        secure=request.secure,
    )
    return response
