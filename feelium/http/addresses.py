"""Where the headset can reach the server: every IPv4 address of the machine when bound to all interfaces.

A server bound to ``0.0.0.0`` answers on every interface, so printing
``127.0.0.1`` (the old behaviour) told the wearer an address the headset can
never use. :func:`interface_ipv4` asks the kernel for each interface's
address (Linux ``SIOCGIFADDR``; elsewhere the host name's addresses), and
:func:`reachable_hosts` orders them for people: the room's addresses first,
loopback last, then ``hostname.local`` (resolved by mDNS on the headset when
the blimp runs avahi).
"""

from __future__ import annotations

import fcntl
import ipaddress
import socket
import struct

WILDCARD_HOSTS = frozenset({"", "0.0.0.0", "::"})
_SIOCGIFADDR = 0x8915  # linux/sockios.h: an interface's IPv4 address


def interface_ipv4() -> list[str]:
    """The IPv4 address of every interface that has one (loopback included)."""
    found: list[str] = []
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for _, name in socket.if_nameindex():
            try:
                reply = fcntl.ioctl(probe.fileno(), _SIOCGIFADDR, struct.pack("256s", name.encode()[:15]))
            except OSError:  # no IPv4 address on this interface
                continue
            found.append(socket.inet_ntoa(reply[20:24]))
    except OSError:
        pass
    finally:
        probe.close()
    if not found:  # not Linux: what the host name resolves to
        try:
            found = [str(info[4][0]) for info in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)]
        except OSError:
            found = []
    return found


def reachable_hosts(bound: str, addresses: list[str], hostname: str) -> list[str]:
    """The host names a client may use for a server bound to ``bound``, most useful first (pure).

    A specific address is the only one; a wildcard gives the non-loopback ``addresses``, then loopback,
    then ``hostname.local``.
    """
    if bound not in WILDCARD_HOSTS:
        return [bound]
    unique = list(dict.fromkeys(a for a in addresses if a))
    room = [a for a in unique if not ipaddress.ip_address(a).is_loopback]
    local = [a for a in unique if ipaddress.ip_address(a).is_loopback] or ["127.0.0.1"]
    names = [f"{hostname.split('.')[0]}.local"] if hostname else []
    return room + local + names


def url_host(host: str) -> str:
    """``host`` as it goes into a URL (IPv6 literals in brackets)."""
    return f"[{host}]" if ":" in host else host
