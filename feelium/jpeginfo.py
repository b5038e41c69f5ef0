"""A JPEG's pixel size read from its header, and the reduced decode that gives a needed size.

Decoding allocates by the size the header declares, not by the bytes sent: a
2 MB upload can declare 8000x8000 pixels and cost 192 MB decoded (more for a
progressive JPEG, whose coefficients are all kept until the last scan). The
headset link refuses images above a pixel limit from the header alone, and
the projector decodes at 1/2, 1/4 or 1/8 scale (libjpeg scales inside the
inverse DCT, so the full image is never in memory) when its canvas needs less.
Shared by ``http`` (the check) and ``projector`` (the decode), which may not
import each other.
"""

from __future__ import annotations

# Start-of-frame markers carry the frame size: SOF0..SOF15 except DHT (C4), JPG (C8) and DAC (CC).
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# Markers without a length field (TEM, RSTn, SOI; EOI ends the image).
_STANDALONE = frozenset({0x01, *range(0xD0, 0xD9)})
_SOS, _EOI = 0xDA, 0xD9
REDUCTIONS = (8, 4, 2, 1)


class JpegHeaderError(ValueError):
    """The bytes are not a JPEG whose frame header can be read."""


def jpeg_size(data: bytes) -> tuple[int, int]:
    """``(width, height)`` from the first start-of-frame segment, without decoding anything."""
    if not data.startswith(b"\xff\xd8"):
        raise JpegHeaderError("not a JPEG (no FF D8 start marker)")
    i, n = 2, len(data)
    while i + 4 <= n:
        if data[i] != 0xFF:
            raise JpegHeaderError(f"corrupt JPEG header: no marker at byte {i}")
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte before a marker
            i += 1
            continue
        if marker in _STANDALONE:
            i += 2
            continue
        if marker in (_SOS, _EOI):
            break
        length = int.from_bytes(data[i + 2 : i + 4], "big")
        if length < 2:
            raise JpegHeaderError(f"corrupt JPEG header: segment length {length} at byte {i}")
        if marker in _SOF:
            if i + 9 > n:
                break
            height = int.from_bytes(data[i + 5 : i + 7], "big")
            width = int.from_bytes(data[i + 7 : i + 9], "big")
            if width == 0 or height == 0:
                raise JpegHeaderError(f"JPEG declares an empty frame ({width}x{height})")
            return width, height
        i += 2 + length
    raise JpegHeaderError("JPEG has no frame header (SOF) before its image data")


def reduction_for(width: int, height: int, need_width: int, need_height: int) -> int:
    """The largest of 8, 4, 2, 1 that still leaves at least ``need_width`` x ``need_height`` pixels."""
    for factor in REDUCTIONS:
        if -(-width // factor) >= need_width and -(-height // factor) >= need_height:
            return factor
    return 1
