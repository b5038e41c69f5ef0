"""Which ``Host`` a request may name: the defence against DNS rebinding.

A page on ``http://evil.example`` can make its own name resolve to the
blimp's address; the browser then treats the blimp as evil.example's origin,
and the same-origin check (``Origin`` equal to ``scheme://Host``) passes.
What such a request cannot hide is its ``Host: evil.example``. So a request
is served only when its Host is a configured name, the machine's hostname,
``hostname.local``, ``localhost``, or an IP literal that is the very address
the connection arrived on (an address is no name an attacker controls, and
checking the connection's own address keeps working when DHCP hands the
blimp a new one after start). Pure: names and addresses are inputs.
"""

from __future__ import annotations

import ipaddress


def split_host(header: str) -> str:
    """The host part of a ``Host`` header (``name:port``, ``[v6]:port``), lower-case, without a trailing dot."""
    host = header.strip().lower()
    if host.startswith("["):
        host = host[1:].partition("]")[0]
    elif host.count(":") == 1:
        host = host.partition(":")[0]
    return host.rstrip(".")


def _address(text: str | None) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    """``text`` as an IP address (an IPv4-mapped IPv6 one as IPv4, as a dual-stack socket reports it), else None."""
    try:
        address = ipaddress.ip_address(text or "")
    except ValueError:
        return None
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        return address.ipv4_mapped
    return address


class HostAllowList:
    """The names a client may put in ``Host`` (and so in the ``Origin`` of the browser client's own page)."""

    def __init__(self, names: frozenset[str]) -> None:
        self.names = frozenset(split_host(n) for n in names if n.strip())

    @classmethod
    def from_config(cls, configured: str, hostname: str) -> "HostAllowList":
        """``[http] allowed_hosts`` (comma-separated) when set, else hostname, hostname.local and localhost."""
        if configured.strip():
            return cls(frozenset(configured.split(",")))
        short = hostname.split(".")[0]
        return cls(frozenset({hostname, short, f"{short}.local", "localhost"} - {""}))

    def allows(self, host_header: str | None, local_address: str | None) -> bool:
        """Whether a request with this ``Host`` that arrived on ``local_address`` may be served."""
        if not host_header:
            return False  # HTTP/1.1 requires Host; without one there is nothing to check it against
        host = split_host(host_header)
        if host in self.names:
            return True
        address = _address(host)
        return address is not None and address == _address(local_address)
