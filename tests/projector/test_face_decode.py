"""The wearer's face is decoded no larger than the skin canvas needs, and the worst upload the link admits
stays far below the board's memory (issue 14: an 8000x8000 JPEG once took 542 MB)."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from feelium.http.config import HttpConfig
from feelium.jpeginfo import reduction_for
from feelium.projector.service import decode_reduced

RSS_BUDGET_MB = 50.0


def _jpeg(width: int, height: int, progressive: bool = False) -> bytes:
    rng = np.random.default_rng(3)
    coarse = rng.integers(0, 255, (max(1, height // 16), max(1, width // 16), 3), np.uint8)
    image = cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC)
    params = [cv2.IMWRITE_JPEG_QUALITY, 95, cv2.IMWRITE_JPEG_PROGRESSIVE, int(progressive),
              cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444]  # fmt: skip
    ok, buf = cv2.imencode(".jpg", image, params)
    assert ok
    return buf.tobytes()


@pytest.mark.parametrize("size, expected", [((2048, 1536), (512, 384)), ((1100, 800), (550, 400)), ((640, 480), (640, 480)), ((256, 256), (256, 256))])
def test_the_decode_is_reduced_only_as_far_as_the_canvas_allows(size, expected) -> None:  # type: ignore[no-untyped-def]
    image = decode_reduced(_jpeg(*size), 512, 384)
    assert image is not None and (image.shape[1], image.shape[0]) == expected


def test_an_unreadable_face_is_none() -> None:
    assert decode_reduced(b"not a jpeg", 512, 384) is None
    assert decode_reduced(b"\xff\xd8\xff\xd9", 512, 384) is None


@pytest.mark.slow
def test_the_largest_face_the_link_admits_decodes_within_the_memory_budget(tmp_path: Path) -> None:
    """Peak RSS growth of a fresh process decoding the worst admissible face: a square progressive 4:4:4 JPEG
    of ``[http] max_face_pixels`` (libjpeg keeps a progressive image's coefficients whole, even when it scales)."""
    side = math.isqrt(HttpConfig().max_face_pixels)
    path = tmp_path / "face.jpg"
    path.write_bytes(_jpeg(side, side, progressive=True))
    script = textwrap.dedent(f"""
        import resource
        from feelium.projector.service import decode_reduced
        data = open({str(path)!r}, "rb").read()
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        image = decode_reduced(data, 512, 384)
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        print(image.shape[1], image.shape[0], (after - before) / 1024.0)
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True)
    width, height, growth_mb = out.stdout.split()
    factor = reduction_for(side, side, 512, 384)  # libjpeg's largest 1/2^k scale that still covers the canvas
    assert factor > 1 and (int(width), int(height)) == (-(-side // factor), -(-side // factor))
    assert float(growth_mb) < RSS_BUDGET_MB, f"decoding a {side}x{side} progressive face grew RSS by {growth_mb} MB"
