"""A camera's MJPEG frame made forwardable: the standard Huffman tables inserted where the camera left them out.

Why: USB (UVC) cameras commonly send MJPEG frames without a DHT (Huffman table) segment, the "AVI1" MJPEG
convention: a decoder is to use the example tables of ITU-T T.81 Annex K.3, which were made the standard tables
for this purpose. libjpeg (and so OpenCV) does; browsers and Apple's decoders may refuse such a frame. The daemon
forwards camera JPEGs to the headset without decoding them, so it inserts those tables before the first scan.

Only the header is walked, marker by marker (a few segments, microseconds): nothing is decoded. What is checked is
what forwarding needs: a start-of-image, well-formed segments up to the first scan, and an end-of-image after it
(so a frame cut short in transfer is not sent as a whole one). Anything else raises :class:`MjpegError`.
"""

from __future__ import annotations

SOI = 0xD8
EOI = 0xD9
SOS = 0xDA
DHT = 0xC4
STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})  # TEM and RST0-7: markers without a length field (T.81 B.1.1.3)


class MjpegError(ValueError):
    """The bytes are not a JPEG that can be forwarded (not one, or cut short); says where it broke."""


def _table(table_class: int, table_id: int, counts: tuple[int, ...], values: bytes) -> bytes:
    """One table of a DHT segment: Tc/Th, the 16 code counts per length (BITS) and the values (HUFFVAL)."""
    assert len(counts) == 16 and sum(counts) == len(values)
    return bytes([table_class << 4 | table_id, *counts]) + values


# ITU-T T.81 (09/92), Annex K.3, the typical Huffman tables for 8-bit precision (baseline) images:
# Table K.3 (DC luminance), K.4 (DC chrominance), K.5 (AC luminance), K.6 (AC chrominance), given there as BITS
# (how many codes of each length 1..16) and HUFFVAL (the symbols in order of code length), as they go into a DHT.
_DC_VALUES = bytes(range(12))
_DC_LUMINANCE = _table(0, 0, (0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0), _DC_VALUES)
_DC_CHROMINANCE = _table(0, 1, (0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0), _DC_VALUES)
_AC_LUMINANCE = _table(
    1, 0, (0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7D),
    bytes.fromhex(
        "01020300041105122131410613516107227114328191a1082342b1c11552d1f0"
        "2433627282090a161718191a25262728292a3435363738393a434445464748494a"
        "535455565758595a636465666768696a737475767778797a838485868788898a"
        "92939495969798999aa2a3a4a5a6a7a8a9aab2b3b4b5b6b7b8b9bac2c3c4c5c6c7"
        "c8c9cad2d3d4d5d6d7d8d9dae1e2e3e4e5e6e7e8e9eaf1f2f3f4f5f6f7f8f9fa"
    ),
)  # fmt: skip
_AC_CHROMINANCE = _table(
    1, 1, (0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77),
    bytes.fromhex(
        "000102031104052131061241510761711322328108144291a1b1c109233352f0"
        "156272d10a162434e125f11718191a262728292a35363738393a434445464748"
        "494a535455565758595a636465666768696a737475767778797a82838485868788"
        "898a92939495969798999aa2a3a4a5a6a7a8a9aab2b3b4b5b6b7b8b9bac2c3c4c5"
        "c6c7c8c9cad2d3d4d5d6d7d8d9dae2e3e4e5e6e7e8e9eaf2f3f4f5f6f7f8f9fa"
    ),
)  # fmt: skip
_TABLES = _DC_LUMINANCE + _AC_LUMINANCE + _DC_CHROMINANCE + _AC_CHROMINANCE
STANDARD_DHT = b"\xff\xc4" + (2 + len(_TABLES)).to_bytes(2, "big") + _TABLES
"""The four Annex K.3 tables as one DHT segment, marker included (420 bytes)."""


def _first_scan(data: bytes) -> tuple[int, bool]:
    """Where the first SOS marker starts and whether a DHT segment came before it."""
    if len(data) < 2 or data[0] != 0xFF or data[1] != SOI:
        raise MjpegError(f"not a JPEG: starts with {data[:2].hex() or 'nothing'}, not the start-of-image ffd8")
    pos, seen_tables, end = 2, False, len(data)
    while True:
        if pos >= end:
            raise MjpegError(f"cut short at byte {pos} of the header, before any scan")
        if data[pos] != 0xFF:
            raise MjpegError(f"byte {pos} is {data[pos]:02x} where a marker (ff..) should start")
        while pos + 1 < end and data[pos + 1] == 0xFF:  # fill bytes before a marker (T.81 B.1.1.2)
            pos += 1
        if pos + 1 >= end:
            raise MjpegError(f"cut short at byte {pos} of the header, before any scan")
        marker = data[pos + 1]
        if marker == SOS:
            return pos, seen_tables
        if marker in (SOI, EOI):
            raise MjpegError(f"marker ff{marker:02x} at byte {pos}, before any scan")
        if marker in STANDALONE:
            pos += 2
            continue
        if pos + 4 > end:
            raise MjpegError(f"cut short in the ff{marker:02x} segment at byte {pos}")
        length = data[pos + 2] << 8 | data[pos + 3]
        if length < 2 or pos + 2 + length > end:
            left = end - pos - 2
            raise MjpegError(f"the ff{marker:02x} segment at byte {pos} claims {length} bytes; {left} are left")
        seen_tables = seen_tables or marker == DHT
        pos += 2 + length


def with_huffman_tables(data: bytes) -> bytes:
    """``data`` with :data:`STANDARD_DHT` inserted before its first scan when no DHT precedes that scan.

    A frame that has its tables comes back as the same object (no copy). Raises :class:`MjpegError` for bytes
    that are not a JPEG, a header cut short or malformed, or no end-of-image after the scan (a truncated frame;
    trailing padding after the end-of-image, which some cameras send, is fine).
    """
    sos, seen_tables = _first_scan(data)
    if sos + 4 > len(data):
        raise MjpegError(f"cut short in the scan header at byte {sos}")
    length = data[sos + 2] << 8 | data[sos + 3]
    scan = sos + 2 + length  # where the entropy-coded data starts
    if length < 8 or scan > len(data):  # Ls = 6 + 2 x Ns, at least one component (T.81 B.2.3)
        raise MjpegError(f"the scan header at byte {sos} claims {length} bytes ({len(data) - sos - 2} are left)")
    if data.rfind(b"\xff\xd9", scan) < 0:  # entropy-coded data never holds ff d9 (ff is stuffed, T.81 F.1.2.3)
        raise MjpegError(f"no end-of-image after the scan at byte {sos}: the frame is cut short ({len(data)} bytes)")
    if seen_tables:
        return data
    return data[:sos] + STANDARD_DHT + data[sos:]
