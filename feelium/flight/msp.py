"""MultiWii Serial Protocol framing: encoders and an incremental parser that never gives up.

The serial line to the motor board carries bytes, not frames: a reconnect,
a brown-out or electrical noise can leave half a frame, garbage, a wrong
checksum or a length byte that promises more data than any frame holds. The
parser keeps a small buffer, looks for a ``$`` that starts a plausible
header, and on any failure drops exactly one byte and looks again, so a good
frame right after a bad one is never lost. Every kind of failure is counted;
none raises.

Frames we send are MSP v2 (``$X``, CRC8 DVB-S2 over flag, command, size and
payload); replies in v1 (``$M``, XOR checksum) are understood too, because
small flight controllers answer old commands that way.
"""

from __future__ import annotations

import functools
import struct
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

Direction = Literal["<", ">", "!"]  # request, reply, error reply
V1_HEADER = b"$M"
V2_HEADER = b"$X"
V1_JUMBO = 255
DEFAULT_MAX_PAYLOAD = 256  # our largest frame is 16 bytes; a bigger length is noise
_V2 = ord("X")
_KINDS = frozenset(b"MX")
_DIRECTIONS = frozenset(b"<>!")
_V2_HEADER = struct.Struct("<BHH")
_BAD = object()  # a frame that failed its checks: the parser steps one byte on


def _crc8_dvb_s2_bitwise(data: bytes | bytearray, crc: int = 0) -> int:
    """CRC8 with polynomial 0xD5 (DVB-S2), bit by bit: the definition the table below is built from."""
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0xD5) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


# One lookup per byte instead of eight shifts: every frame of every control tick is checked (50 Hz, ~11 frames).
_CRC8_TABLE = tuple(_crc8_dvb_s2_bitwise(bytes([byte])) for byte in range(256))


def crc8_dvb_s2(data: bytes | bytearray, crc: int = 0) -> int:
    """CRC8 with polynomial 0xD5 (DVB-S2), as MSP v2 specifies."""
    table = _CRC8_TABLE
    for byte in data:
        crc = table[crc ^ byte]
    return crc


def xor_checksum(data: bytes | bytearray) -> int:
    """The MSP v1 checksum: XOR of size, command and payload bytes."""
    crc = 0
    for byte in data:
        crc ^= byte
    return crc


class MspFrame(NamedTuple):
    """One decoded frame: version 1 or 2, direction, command, payload.

    A named tuple, not a frozen dataclass: the control loop decodes ~5 a tick, and a frozen dataclass's
    ``__init__`` (one ``object.__setattr__`` per field) cost three times as much to build.
    """

    version: int
    direction: Direction
    command: int
    payload: bytes = b""
    flags: int = 0

    @property
    def is_error(self) -> bool:
        return self.direction == "!"


def encode_v2(command: int, payload: bytes = b"", direction: Direction = "<", flags: int = 0) -> bytes:
    """An MSP v2 frame (``$X``) for ``command`` (0..65535)."""
    if not payload:
        return _encode_v2_empty(command, direction, flags)
    return _encode_v2(command, payload, direction, flags)


@functools.lru_cache(maxsize=64)
def _encode_v2_empty(command: int, direction: Direction, flags: int) -> bytes:
    """A frame without payload (every telemetry request), built once: the control loop asks the same few each tick."""
    return _encode_v2(command, b"", direction, flags)


def _encode_v2(command: int, payload: bytes, direction: Direction, flags: int) -> bytes:
    if not 0 <= command <= 0xFFFF:
        raise ValueError(f"MSP v2 command must be 0..65535, got {command}")
    if len(payload) > 0xFFFF:
        raise ValueError(f"MSP v2 payload must be at most 65535 bytes, got {len(payload)}")
    body = struct.pack("<BHH", flags & 0xFF, command, len(payload)) + bytes(payload)
    return V2_HEADER + direction.encode() + body + bytes([crc8_dvb_s2(body)])


def encode_v1(command: int, payload: bytes = b"", direction: Direction = "<") -> bytes:
    """An MSP v1 frame (``$M``) for ``command`` (0..254, payload under 255 bytes)."""
    if not 0 <= command <= 254:
        raise ValueError(f"MSP v1 command must be 0..254, got {command}")
    if len(payload) >= V1_JUMBO:
        raise ValueError(f"MSP v1 payload must be under 255 bytes, got {len(payload)}")
    body = bytes([len(payload), command]) + bytes(payload)
    return V1_HEADER + direction.encode() + body + bytes([xor_checksum(body)])


@dataclass
class ParserCounters:
    """What the parser saw besides good frames; exported in health()."""

    frames: int = 0
    error_replies: int = 0
    garbage_bytes: int = 0
    bad_checksums: int = 0
    oversized: int = 0
    truncated: int = 0

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


@dataclass
class MspParser:
    """Feed it bytes in any chunking; it returns the complete frames found so far."""

    max_payload: int = DEFAULT_MAX_PAYLOAD
    counters: ParserCounters = field(default_factory=ParserCounters)
    _buffer: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes | bytearray) -> list[MspFrame]:
        """Append ``data`` and return every frame now complete, oldest first.

        One pass over the buffer with an index, the consumed bytes dropped once at the end: a
        control tick parses ~6 frames, and a method call, a ``del`` of the buffer's head and a
        status string per frame cost more than the checks themselves. On any failure it steps
        one byte on and looks again, as the module says.
        """
        buf = self._buffer
        buf += data
        counters = self.counters
        frames: list[MspFrame] = []
        size_limit = self.max_payload
        n = len(buf)
        pos = 0
        while pos < n:
            start = buf.find(b"$", pos)
            if start < 0:
                counters.garbage_bytes += n - pos
                pos = n
                break
            if start > pos:
                counters.garbage_bytes += start - pos
                pos = start
            if n - pos < 3:
                break
            kind = buf[pos + 1]  # as ints: slicing out one-byte strings cost more than the rest of the check
            if kind not in _KINDS or buf[pos + 2] not in _DIRECTIONS:
                counters.garbage_bytes += 1
                pos += 1
                continue
            frame = self._v2_at(buf, pos, n, size_limit) if kind == _V2 else self._v1_at(buf, pos, n, size_limit)
            if frame is None:  # incomplete: wait for more bytes
                break
            if frame is _BAD:
                pos += 1
                continue
            frame, pos = frame
            counters.frames += 1
            if frame.direction == "!":
                counters.error_replies += 1
            frames.append(frame)
        if pos:
            del buf[:pos]
        return frames

    def pending(self) -> int:
        """Bytes held waiting for the rest of a frame."""
        return len(self._buffer)

    def abandon(self) -> None:
        """Drop a partial frame that stopped arriving (called after a read timeout)."""
        if self._buffer:
            if self._buffer[:1] == b"$":
                self.counters.truncated += 1
            else:
                self.counters.garbage_bytes += len(self._buffer)
            self._buffer.clear()

    def _v1_at(self, buf: bytearray, pos: int, n: int, size_limit: int) -> tuple[MspFrame, int] | object | None:
        """The v1 frame at ``pos`` and the index after it; ``_BAD`` (counted) or ``None`` (incomplete)."""
        if n - pos < 5:
            return None
        size, command = buf[pos + 3], buf[pos + 4]
        header = pos + 5
        if size == V1_JUMBO:
            if n - pos < 7:
                return None
            size = buf[pos + 5] | (buf[pos + 6] << 8)
            header = pos + 7
        if size > size_limit:
            self.counters.oversized += 1
            return _BAD
        end = header + size
        if n < end + 1:
            return None
        if xor_checksum(buf[pos + 3 : end]) != buf[end]:
            self.counters.bad_checksums += 1
            return _BAD
        return MspFrame(1, chr(buf[pos + 2]), command, bytes(buf[header:end])), end + 1  # type: ignore[arg-type]

    def _v2_at(self, buf: bytearray, pos: int, n: int, size_limit: int) -> tuple[MspFrame, int] | object | None:
        """The v2 frame at ``pos`` and the index after it; ``_BAD`` (counted) or ``None`` (incomplete)."""
        if n - pos < 8:
            return None
        flags, command, size = _V2_HEADER.unpack_from(buf, pos + 3)
        if size > size_limit:
            self.counters.oversized += 1
            return _BAD
        end = pos + 8 + size
        if n < end + 1:
            return None
        crc = 0
        table = _CRC8_TABLE
        for byte in buf[pos + 3 : end]:
            crc = table[crc ^ byte]
        if crc != buf[end]:
            self.counters.bad_checksums += 1
            return _BAD
        return MspFrame(2, chr(buf[pos + 2]), command, bytes(buf[pos + 8 : end]), flags), end + 1  # type: ignore[arg-type]
