"""Huffman tables inserted into MJPEG frames that leave them out (the UVC "AVI1" convention), by a marker scan."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.cameras.mjpeg import STANDARD_DHT, MjpegError, with_huffman_tables


def _segments(data: bytes) -> list[tuple[int, int, int]]:
    """(marker, start, end) of each header segment up to the first scan (the test's own simple walk)."""
    found, pos = [], 2
    while data[pos + 1] != 0xDA:
        end = pos + 2 + (data[pos + 2] << 8 | data[pos + 3])
        found.append((data[pos + 1], pos, end))
        pos = end
    return found


def _strip_tables(data: bytes) -> bytes:
    """What a UVC camera sends: the JPEG without its DHT segments."""
    for marker, start, end in reversed(_segments(data)):
        if marker == 0xC4:
            data = data[:start] + data[end:]
    return data


@pytest.fixture(scope="module")
def frame() -> tuple[np.ndarray, bytes]:
    """A 640x480 colour frame with detail (gradients, noise, edges) and its JPEG from OpenCV (standard tables)."""
    rng = np.random.default_rng(7)
    y, x = np.mgrid[0:480, 0:640]
    image = np.dstack([(x * 255 // 639), (y * 255 // 479), ((x + y) % 256)]).astype(np.uint8)
    image = cv2.add(image, rng.integers(0, 40, image.shape, dtype=np.uint8))
    cv2.circle(image, (320, 240), 100, (255, 255, 255), 5)
    ok, encoded = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])
    assert ok
    return image, encoded.tobytes()


def test_the_tables_are_the_standard_ones_opencv_encodes_with(frame):
    _, data = frame
    written = b"".join(data[start + 4 : end] for marker, start, end in _segments(data) if marker == 0xC4)
    assert written == STANDARD_DHT[4:] and len(STANDARD_DHT) == 420


def test_a_frame_without_tables_decodes_exactly_as_the_original_once_they_are_inserted(frame):
    _, data = frame
    stripped = _strip_tables(data)
    assert b"\xff\xc4" not in stripped[: stripped.index(b"\xff\xda")]
    fixed = with_huffman_tables(stripped)
    assert len(fixed) == len(stripped) + len(STANDARD_DHT)
    assert fixed.index(STANDARD_DHT) == stripped.index(b"\xff\xda")  # right before the first scan
    original = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    decoded = cv2.imdecode(np.frombuffer(fixed, np.uint8), cv2.IMREAD_COLOR)
    assert decoded is not None and np.array_equal(decoded, original)


def test_a_frame_with_its_tables_is_the_same_object(frame):
    _, data = frame
    assert with_huffman_tables(data) is data


def test_fill_bytes_standalone_markers_and_trailing_padding_are_accepted(frame):
    _, data = frame
    stripped = _strip_tables(data)
    sos = stripped.index(b"\xff\xda")
    padded = stripped[:sos] + b"\xff\xff\xff\xd0" + stripped[sos:] + b"\x00" * 64  # fill, an RST, the camera's padding
    fixed = with_huffman_tables(padded)
    assert fixed[: sos + 4] == padded[: sos + 4] and fixed[sos + 4 : sos + 4 + len(STANDARD_DHT)] == STANDARD_DHT


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (b"", "not a JPEG"),
        (b"GIF89a......", "not a JPEG"),
        (b"\xff\xd8", "cut short"),
        (b"\xff\xd8\xff\xe0\x00\x10JFIF", "claims 16 bytes"),
        (b"\xff\xd8\xff\xe0\x00\x01\xff\xda", "claims 1 bytes"),
        (b"\xff\xd8\x00\x00", "where a marker"),
        (b"\xff\xd8\xff\xd9", "before any scan"),
        (b"\xff\xd8\xff\xda\x00", "scan header"),
        (b"\xff\xd8\xff\xda\x00\x02\xff\xd9", "scan header at byte 2 claims 2 bytes"),
        (b"\xff\xd8\xff\xda\x00\x20\x01\x01\x00\xff\xd9", "scan header at byte 2 claims 32 bytes"),
        (b"\xff\xd8\xff\xda\x00\x08\x01\x01\x00\x00\x3f\x00\x12\x34", "no end-of-image"),
    ],
)
def test_what_is_not_a_whole_jpeg_raises_saying_why(data, words):
    with pytest.raises(MjpegError, match=words):
        with_huffman_tables(data)


def test_a_frame_cut_short_in_its_scan_raises(frame):
    _, data = frame
    stripped = _strip_tables(data)
    with pytest.raises(MjpegError, match="cut short"):
        with_huffman_tables(stripped[: len(stripped) // 2])


@settings(max_examples=300, deadline=None)
@given(cut=st.floats(0.0, 1.0), strip=st.booleans(), noise=st.binary(max_size=32), at=st.floats(0.0, 1.0))
def test_any_cut_or_corruption_gives_a_jpeg_or_the_documented_error(frame, cut, strip, noise, at):
    _, data = frame
    source = _strip_tables(data) if strip else data
    head = source[: round(cut * len(source))]
    where = round(at * len(head))
    damaged = head[:where] + noise + head[where + len(noise) :]
    try:
        fixed = with_huffman_tables(damaged)
    except MjpegError:
        return
    assert fixed[:2] == b"\xff\xd8" and b"\xff\xd9" in fixed
    assert fixed is damaged or STANDARD_DHT in fixed


@settings(max_examples=500, deadline=None)
@given(blob=st.binary(max_size=600), soi=st.booleans())
def test_arbitrary_bytes_give_a_jpeg_or_the_documented_error(blob, soi):
    data = (b"\xff\xd8" if soi else b"") + blob
    try:
        fixed = with_huffman_tables(data)
    except MjpegError:
        return
    assert fixed[:2] == b"\xff\xd8" and (fixed is data or STANDARD_DHT in fixed)
