"""The blimp's Bonjour advertisement: an avahi service file for ``_feelium._tcp``.

Raspberry Pi OS already runs avahi-daemon, which answers ``<hostname>.local``
and publishes every service file in ``/etc/avahi/services/``. Publishing
through it, rather than from the daemon with python-zeroconf, keeps one mDNS
responder on the machine (two would share UDP 5353 and answer for the same
host name), adds no dependency to a 512 MB board and needs no privilege in
the hardened service unit. The cost: the advertisement outlives a stopped
daemon, so a client that finds the blimp must still expect a refused
connection (it retries, as after any link loss).

The TXT record tells a client what it needs before its first request: the
API's path and whether the server speaks HTTPS (the port is the SRV record's).
"""

from __future__ import annotations

from xml.sax.saxutils import escape

SERVICE_TYPE = "_feelium._tcp"
API_PATH = "/api/v1"
# avahi replaces %h with the host name, so every blimp in a room has its own instance name
DEFAULT_INSTANCE_NAME = "Feelium on %h"


def txt_records(tls: bool) -> list[str]:
    """The TXT record's key=value strings (txtvers first, as DNS-SD recommends)."""
    return ["txtvers=1", f"path={API_PATH}", f"scheme={'https' if tls else 'http'}", "auth=token"]


def avahi_service_file(port: int, tls: bool, instance_name: str = DEFAULT_INSTANCE_NAME) -> str:
    """The XML avahi-daemon reads from ``/etc/avahi/services/feelium.service`` (avahi.service(5))."""
    if not 0 < port < 65536:
        raise ValueError(f"an advertised port must be 1..65535, got {port}")
    txt = "".join(f"    <txt-record>{escape(record)}</txt-record>\n" for record in txt_records(tls))
    return (
        '<?xml version="1.0" standalone="no"?>\n'
        '<!DOCTYPE service-group SYSTEM "avahi-service.dtd">\n'
        "<!-- written by `feelium mdns-service`; rewrite it when [http] port or TLS changes -->\n"
        "<service-group>\n"
        f'  <name replace-wildcards="yes">{escape(instance_name)}</name>\n'
        "  <service>\n"
        f"    <type>{SERVICE_TYPE}</type>\n"
        f"    <port>{port}</port>\n"
        f"{txt}"
        "  </service>\n"
        "</service-group>\n"
    )
