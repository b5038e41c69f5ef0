"""Who a request comes from: the key of the per-client rate limits, stream slots and the motion lease.

Every client holds the same bearer token, so the token cannot tell two
headsets apart; the client identity is the remote address plus an optional
id the client picks itself (``X-Feelium-Client`` header, or ``?client=``
where headers cannot be set, e.g. an ``<img>`` stream). Two apps on one
device (or behind one NAT) are one client unless they send different ids.
An id is no secret and proves nothing: it only keeps honest clients apart;
every client is already authenticated by the token. An id outside the
pattern is ignored rather than refused, so a client's ``stop`` never fails
on its id. Since ids are free to pick, the limits also hold per address
(``[http] clients_per_address``): new ids from one device add nothing
beyond that.
"""

from __future__ import annotations

import re

from aiohttp import web


CLIENT_HEADER = "X-Feelium-Client"
CLIENT_ID_PATTERN = r"^[A-Za-z0-9._:-]{1,64}$"
_VALID = re.compile(CLIENT_ID_PATTERN)


def client_key(remote: str | None, client_id: str | None) -> str:
    """The client's identity: ``address`` or ``address/id``."""
    address = remote or "local"
    return address if not client_id else f"{address}/{client_id}"


def address_of(client: str) -> str:
    """The address part of a client key: what an id cannot change."""
    return client.split("/", 1)[0]


def client_of(request: web.Request) -> str:
    """The identity of ``request``'s client (an id outside :data:`CLIENT_ID_PATTERN` is ignored)."""
    chosen = request.headers.get(CLIENT_HEADER) or request.query.get("client") or None
    if chosen is not None and not _VALID.fullmatch(chosen):
        chosen = None
    return client_key(request.remote, chosen)
