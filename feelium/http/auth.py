"""The bearer token: everyone on the room's Wi-Fi can reach the blimp, only the wearer may drive it.

The token comes from the config, or from a file created with mode 0600 on
first run. Requests carry it as ``Authorization: Bearer ...``; browsers'
``<img>``, ``EventSource`` and ``WebSocket`` cannot set headers, so
``?token=...`` is accepted too. Comparison is constant-time.
"""

from __future__ import annotations

import hmac
import logging
import os
import secrets
import stat
from collections.abc import Mapping
from pathlib import Path

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
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as exc:
        raise TokenError(f"{path}: cannot create the token file: {exc.strerror}") from exc
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


def presented_token(headers: Mapping[str, str], query: Mapping[str, str]) -> str | None:
    """The token a request carries: the bearer header first, then ``?token=``."""
    auth = headers.get("Authorization", "")
    scheme, _, value = auth.partition(" ")
    if scheme.lower() == "bearer" and value.strip():
        return value.strip()
    return query.get("token") or None


def token_matches(presented: str | None, expected: str) -> bool:
    """Constant-time comparison (the time does not depend on where the strings differ)."""
    if presented is None:
        return False
    return hmac.compare_digest(presented.encode("utf-8", "surrogateescape"), expected.encode("utf-8"))
