"""The bearer token: everyone on the room's Wi-Fi can reach the blimp, only the wearer may drive it.

The token comes from the config, or from a file created with mode 0600 on
first run. Requests carry it as ``Authorization: Bearer ...``; browsers'
``<img>``, ``EventSource`` and ``WebSocket`` cannot set headers, so
``?token=...`` is accepted too. Comparison is constant-time.

A file token can be rotated without a restart: :func:`write_new_token`
replaces the file atomically (``feelium token rotate``, or ``POST
/token/rotate``), and :class:`TokenStore` notices a changed file within a
second, so a leaked token stops working at once and nobody restarts the blimp.
"""

from __future__ import annotations

import hmac
import logging
import os
import secrets
import stat
from collections.abc import Mapping
from pathlib import Path

from aiohttp import web

log = logging.getLogger(__name__)

TOKEN_BYTES = 24


class TokenError(ValueError):
    """The token file cannot be read or created; names the file."""


def load_or_create_token(configured: str, token_file: str) -> str:
    """``configured`` when set, else the token in ``token_file`` (created 0600 when missing)."""
    if configured:
        return configured
    path = Path(token_file).expanduser()
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        return _read_token(path)
    except FileNotFoundError:
        try:
            path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except OSError as exc:
            raise TokenError(f"{path}: cannot create the token file ([http] token_file): {exc.strerror}") from exc
    except OSError as exc:
        raise TokenError(f"{path}: cannot create the token file ([http] token_file): {exc.strerror}") from exc
    token = secrets.token_urlsafe(TOKEN_BYTES)
    with os.fdopen(fd, "w", encoding="ascii") as fh:
        fh.write(token + "\n")
    log.info("generated a new headset token in %s", path)
    return token


def _read_token(path: Path) -> str:
    try:
        mode = path.stat().st_mode
        if mode & (stat.S_IRWXG | stat.S_IRWXO):
            log.warning("%s was readable by others; restricting it to 0600", path)
            path.chmod(0o600)
        token = path.read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise TokenError(f"{path}: cannot read the token file: {exc}") from exc
    if len(token) < 16:
        raise TokenError(f"{path}: the token is shorter than 16 characters; delete the file to generate a new one")
    return token


def write_new_token(token_file: str) -> str:
    """Replace the token in ``token_file`` with a new random one (written 0600, renamed into place)."""
    path = Path(token_file).expanduser()
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    token = secrets.token_urlsafe(TOKEN_BYTES)
    temp = path.with_name(f".{path.name}.{secrets.token_hex(4)}")
    try:
        fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w", encoding="ascii") as fh:
            fh.write(token + "\n")
        os.replace(temp, path)
    except OSError as exc:
        temp.unlink(missing_ok=True)
        raise TokenError(f"{path}: cannot write a new token: {exc.strerror}") from exc
    return token


class TokenStore:
    """The token requests are checked against; follows its file when the token came from one.

    The file is looked at (one ``stat``) at most every ``check_every_s`` of the times passed in, and
    re-read only when it changed; a file that became unreadable keeps the last good token (and logs).
    """

    def __init__(self, token: str, token_file: str | None, check_every_s: float = 1.0) -> None:
        self._token = token
        self.path = Path(token_file).expanduser() if token_file else None
        self.check_every_s = check_every_s
        self._next_check = -float("inf")
        self._stamp = self._file_stamp()
        self.rotations = 0

    def _file_stamp(self) -> tuple[int, int, int] | None:
        if self.path is None:
            return None
        try:
            st = self.path.stat()
        except OSError:
            return None
        return st.st_ino, st.st_mtime_ns, st.st_size

    def current(self, now: float) -> str:
        """The token in force at ``now`` (re-reading the file if it changed since the last look)."""
        if self.path is not None and now >= self._next_check:
            self._next_check = now + self.check_every_s
            stamp = self._file_stamp()
            if stamp is not None and stamp != self._stamp:
                try:
                    token = _read_token(self.path)
                except TokenError as exc:
                    log.error("keeping the previous headset token: %s", exc)
                else:
                    if token != self._token:
                        log.info("headset token changed in %s: the previous one no longer works", self.path)
                        self._token = token
                        self.rotations += 1
                    self._stamp = stamp
        return self._token

    def matches(self, presented: str | None, now: float) -> bool:
        return token_matches(presented, self.current(now))

    def rotate(self) -> str:
        """A new token, in force at once and written to the file; ``TokenError`` when it comes from the config."""
        if self.path is None:
            raise TokenError("the token is set in [http] token: change it there and restart (or use token_file)")
        self._token = write_new_token(str(self.path))
        self._stamp = self._file_stamp()
        self.rotations += 1
        return self._token


SESSION_COOKIE = "feelium_token"


def presented_token(headers: Mapping[str, str], query: Mapping[str, str], cookies: Mapping[str, str] | None = None) -> str | None:
    """The token a request carries: the bearer header first, then the browser's session cookie, then ``?token=``."""
    auth = headers.get("Authorization", "")
    scheme, _, value = auth.partition(" ")
    if scheme.lower() == "bearer" and value.strip():
        return value.strip()
    if cookies and cookies.get(SESSION_COOKIE):
        return cookies[SESSION_COOKIE]
    return query.get("token") or None


def token_of(request: web.Request) -> str | None:
    """The token ``request`` presented (what a long-lived stream is checked against after a rotation)."""
    return presented_token(request.headers, request.query, request.cookies)


def token_matches(presented: str | None, expected: str) -> bool:
    """Constant-time comparison (the time does not depend on where the strings differ)."""
    if presented is None:
        return False
    return hmac.compare_digest(presented.encode("utf-8", "surrogateescape"), expected.encode("utf-8"))
