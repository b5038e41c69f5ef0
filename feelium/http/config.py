"""The ``[http]`` config section."""

from __future__ import annotations

from dataclasses import dataclass

from feelium.settings import setting

MIN_TOKEN_CHARS = 16  # a guess at 62**16 is out of reach; shorter ones are refused where they are written


@dataclass(frozen=True)
class HttpConfig:
    """The headset API server (the wearer's link to the blimp)."""

    enabled: bool = setting(True, "Serve the headset API and the browser client.")
    host: str = setting("127.0.0.1", "Address to listen on; 0.0.0.0 to reach it from the room's Wi-Fi.")
    port: int = setting(8080, "TCP port.", min=0, max=65535)
    token: str = setting(
        "",
        f"Bearer token every endpoint but health requires, at least {MIN_TOKEN_CHARS} characters; empty = read (or "
        "create on first run) token_file.",
    )
    token_file: str = setting(
        "~/.config/feelium/http-token", "Where the generated token lives (created 0600 on first run)."
    )
    cors_origins: str = setting(
        "", "Comma-separated origins (https://host:port) other than the server itself allowed to call the API."
    )
    allowed_hosts: str = setting(
        "", "Comma-separated names clients may use in the Host header (DNS rebinding defence; 403 otherwise). Empty "
        "= the machine's hostname, hostname.local and localhost. The IP address a connection arrived on is always allowed."
    )
    access_log: bool = setting(
        False, "Log every request at debug level (method, path, status, size, time; the token is redacted)."
    )
    pairing_ttl_s: float = setting(
        120.0, "How long a pairing code (feelium pair) may be exchanged for the token; each code works once.",
        min=10.0, max=3600.0,
    )
    tls_cert: str = setting("", "PEM certificate file; with tls_key, the server speaks HTTPS only.")
    tls_key: str = setting("", "PEM private key file for tls_cert.")
    max_json_bytes: int = setting(16384, "Largest JSON request body (413 above).", min=256, max=1048576)
    max_face_bytes: int = setting(
        2_000_000, "Largest face upload: one JPEG, or all frames of a looping avatar (413 above).", min=1024, max=16_000_000
    )
    max_avatar_frames: int = setting(64, "Most frames a looping avatar may have.", min=1, max=1000)
    max_uploads_in_flight: int = setting(
        2, "Face uploads whose bodies are read at once, all clients together; one more gets 429 at once, before its "
        "body is read, so concurrent uploads cannot stack megabytes on a 512 MB board.", min=1, max=16,
    )
    max_speech_bytes: int = setting(
        256_000, "Largest speech upload (one WAV chunk; 413 above).", min=1024, max=4_000_000
    )
    max_json_depth: int = setting(
        8, "Deepest nesting of arrays and objects in a JSON body (400 above); the API's bodies are flat.", min=2, max=64
    )
    max_face_pixels: int = setting(
        2_073_600,
        "Largest face or avatar frame in pixels (width x height, read from the JPEG header before decoding; 413 "
        "above). 1920x1080 fits a video frame whole, and keeps a progressive JPEG's decode (all its coefficients "
        "until the last scan, however reduced) near 15 MB on a 512 MB board; the skin canvas needs only 512x384.",
        min=4096, max=67_108_864,
    )
    motion_rate_per_s: float = setting(
        25.0, "Sustained motion commands per second accepted from one client (headsets refresh the dead man "
        "~7/s); 429 above. stop is never limited.",
        min=1.0, max=1000.0,
    )
    motion_burst: int = setting(25, "Motion commands one client may send in a burst before its limit applies.", min=1, max=1000)
    control_lease_s: float = setting(
        5.0, "Motion is exclusive to one client; its lease lapses after this long without a motion command from "
        "it, and another client may then steer without taking over.",
        min=0.5, max=600.0,
    )
    clients_per_address: int = setting(
        4, "Client ids are free to pick, so the motion, action and speech limits also hold per address at this "
        "many times one client's (a device with a browser and an app fits).", min=1, max=64,
    )
    action_rate_per_s: float = setting(
        4.0, "Sustained wearer actions and face uploads per second accepted from one client; 429 above.",
        min=0.1, max=1000.0,
    )
    action_burst: int = setting(8, "Wearer actions and face uploads one client may send in a burst.", min=1, max=1000)
    speech_rate_per_s: float = setting(
        20.0, "Sustained speech chunks per second accepted from one client (100-200 ms chunks are 5-10/s); 429 above.",
        min=1.0, max=1000.0,
    )
    speech_burst: int = setting(20, "Speech chunks one client may send in a burst.", min=1, max=1000)
    event_ring_size: int = setting(
        512, "Events kept for long-poll, SSE and WebSocket catch-up; a client further behind gets reset.",
        min=8, max=100000,
    )
    longpoll_max_s: float = setting(30.0, "Longest long-poll wait a client may ask for.", min=0.0, max=300.0)
    stream_write_timeout_s: float = setting(
        2.0, "A video, SSE or WebSocket client that accepts nothing for this long is dropped.", min=0.05, max=60.0
    )
    stream_inflight_bytes: int = setting(
        32768, "Video bytes a stream may have unacknowledged before its next frame (about one frame), so a slow "
        "or congested headset gets the newest frame instead of seconds-old queued ones; 0 = no limit.",
        min=0, max=16_000_000,
    )
    max_stream_clients: int = setting(
        16, "Concurrent MJPEG streams in total, all cameras together; more get 429.", min=1, max=1000
    )
    max_streams_per_client: int = setting(
        4, "Concurrent MJPEG streams of one client (all cameras); more get 429.", min=1, max=1000
    )
    max_streams_per_address: int = setting(
        8, "Concurrent MJPEG streams from one address, whatever client ids it sends (ids are free to pick): below "
        "max_stream_clients, so another device always finds a slot; more get 429.", min=1, max=1000
    )
    max_speech_streams: int = setting(
        8, "Concurrent speech streams (GET /speech/stream) in total; more get 429.", min=1, max=1000
    )
    max_speech_streams_per_client: int = setting(
        2, "Concurrent speech streams of one client; more get 429.", min=1, max=100
    )
    max_event_streams: int = setting(
        64, "Concurrent event streams (GET /events/ws and /events/stream) in total; more get 429 (each holds a "
        "socket: unbounded, they would use up the daemon's file descriptors).", min=1, max=1000
    )
    max_event_streams_per_client: int = setting(4, "Concurrent event streams of one client; more get 429.", min=1, max=100)
    max_event_streams_per_address: int = setting(
        16, "Concurrent event streams from one address, whatever client ids it sends; more get 429.", min=1, max=1000
    )
    max_connections: int = setting(
        512, "Open connections in total (each holds a descriptor, whatever it does); one more is closed at once.",
        min=8, max=100000,
    )
    max_connections_per_address: int = setting(
        64, "Open connections from one address (a device), so one that opens thousands cannot use up the daemon's "
        "descriptors while the rest of the room waits; one more is closed at once.", min=4, max=100000,
    )
    socket_messages_per_s: float = setting(
        50.0, "Messages (pings and pongs too) a client may send on one WebSocket per second (burst twice that); a "
        "socket over it is dropped (1006 to the client): each costs the event loop a parse and often a reply even "
        "when refused. Motion at 20 Hz fits.",
        min=1.0, max=10000.0,
    )
    max_speech_streams_per_address: int = setting(
        4, "Concurrent speech streams from one address, whatever client ids it sends; more get 429.", min=1, max=1000
    )
    speech_stream_backlog_ms: int = setting(
        200, "Room audio a speech stream may have unacknowledged on its socket; a frame beyond it is dropped "
        "(counted in the next frame's header), never queued, so a slow headset hears gaps, not a growing delay.",
        min=40, max=5000,
    )
    jpeg_quality: int = setting(80, "JPEG quality of the video streams (encoded once per frame).", min=10, max=100)
    keepalive_s: float = setting(
        15.0, "SSE comment / WebSocket ping interval that keeps idle connections and proxies alive.", min=0.5, max=300.0
    )

    def __post_init__(self) -> None:
        if self.token and len(self.token) < MIN_TOKEN_CHARS:
            # found by `feelium config check`, not by a link that then never starts on the blimp
            raise ValueError(f"token must be at least {MIN_TOKEN_CHARS} characters (or empty to use token_file)")
