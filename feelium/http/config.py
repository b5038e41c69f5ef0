"""The ``[http]`` config section."""

from __future__ import annotations

from dataclasses import dataclass

from feelium.settings import setting


@dataclass(frozen=True)
class HttpConfig:
    """The headset API server."""

    host: str = setting("127.0.0.1", "Address to listen on; 0.0.0.0 to reach it from the room's Wi-Fi.")
    port: int = setting(8080, "TCP port.", min=0, max=65535)
