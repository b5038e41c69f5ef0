"""Speech as a stream: the binary frame of ``GET /speech/stream`` and the rule that keeps a slow reader bounded.

A long-polling headset asks for the room's audio about 25 times a second (one
request per 40 ms chunk); the WebSocket sends each chunk as one binary message
the moment it is captured. Each message is a fixed little-endian header and the
PCM16 samples::

    offset size  field
    0      2     version (1)
    2      2     header_bytes (32): the samples start here; a later version may append fields
    4      4     rate, Hz
    8      8     seq: the chunk's number (the same numbers as X-Speech-Seq of the long-poll)
    16     8     capture_t: when the chunk's last sample was captured, daemon clock, s (see GET /clock)
    24     8     dropped: chunks this client has missed so far (skipped while it was behind)
    32     ...   PCM16 mono little-endian samples

A stream never queues audio per client: the writer reads the shared feed (at
most ``[audio] capture_keep_ms``) and, before each frame, looks at how many
bytes are still unacknowledged on its socket. Above the backlog limit the frame
is dropped (counted, so the client sees the gap), never buffered; when the
backlog has not shrunk for the write timeout the client is given up and its
slot freed. Pure: no I/O, times passed in.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Literal

import numpy as np

from feelium.wav import resample

FRAME_VERSION = 1
_HEADER = struct.Struct("<HHIQdQ")
HEADER_BYTES = _HEADER.size  # 32


@dataclass(frozen=True)
class SpeechFrame:
    """One chunk of room audio as a stream frame."""

    seq: int
    rate: int
    capture_t: float
    dropped: int
    pcm: bytes

    def header_json(self) -> dict[str, float | int]:
        """The header's fields by name (what the OpenAPI ``SpeechFrameHeader`` schema describes)."""
        return {
            "version": FRAME_VERSION, "header_bytes": HEADER_BYTES, "rate": self.rate, "seq": self.seq,
            "capture_t": self.capture_t, "dropped": self.dropped, "samples": len(self.pcm) // 2,
        }  # fmt: skip


def encode_frame(frame: SpeechFrame) -> bytes:
    """The binary WebSocket message of ``frame``."""
    return _HEADER.pack(FRAME_VERSION, HEADER_BYTES, frame.rate, frame.seq, frame.capture_t, frame.dropped) + frame.pcm


def decode_frame(data: bytes) -> SpeechFrame:
    """A frame from its message (clients and tests); ``ValueError`` for a short or malformed one."""
    if len(data) < HEADER_BYTES:
        raise ValueError(f"a speech frame has at least {HEADER_BYTES} header bytes, got {len(data)}")
    version, header_bytes, rate, seq, capture_t, dropped = _HEADER.unpack_from(data)
    if version < 1 or header_bytes < HEADER_BYTES or header_bytes > len(data) or (len(data) - header_bytes) % 2:
        raise ValueError(f"malformed speech frame header (version {version}, header_bytes {header_bytes}, {len(data)} bytes)")
    return SpeechFrame(seq, rate, capture_t, dropped, bytes(data[header_bytes:]))


Decision = Literal["send", "drop", "close"]


class BacklogGate:
    """Per frame: send it, drop it (the reader is behind) or close (the reader has stalled).

    ``backlog`` is what the socket still holds for the client (kernel send queue plus the transport's own
    buffer), or ``None`` where that cannot be read (then every frame is sent and only the write timeout
    guards). A backlog that shrank since the last look is progress: a slow reader loses frames but keeps
    its slot; only one that accepts nothing for ``stall_s`` is closed.
    """

    def __init__(self, max_backlog_bytes: int, stall_s: float) -> None:
        self.max_backlog_bytes = max_backlog_bytes
        self.stall_s = stall_s
        self._last_backlog = 0
        self._last_progress: float | None = None

    def decide(self, backlog: int | None, now: float) -> Decision:
        if self._last_progress is None:
            self._last_progress = now
        if backlog is None or backlog <= self.max_backlog_bytes:
            self._last_backlog = backlog or 0
            self._last_progress = now
            return "send"
        if backlog < self._last_backlog:
            self._last_progress = now
        self._last_backlog = backlog
        return "close" if now - self._last_progress > self.stall_s else "drop"


def incoming_pcm(data: bytes, rate: int, target: int) -> bytes:
    """A wearer's binary message (PCM16 mono little-endian at ``rate``) as PCM16 at ``target``; ``ValueError``
    when it is empty or not whole samples."""
    if not data or len(data) % 2:
        raise ValueError(f"a speech message is PCM16 mono: a non-zero even number of bytes, got {len(data)}")
    samples = np.frombuffer(data, dtype="<i2")
    return resample(samples, rate, target).astype("<i2").tobytes()
