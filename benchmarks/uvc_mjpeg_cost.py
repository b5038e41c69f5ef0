"""CPU per frame of a USB camera's MJPEG forwarded (Huffman tables inserted) against decoding and encoding it again.

    python benchmarks/uvc_mjpeg_cost.py [--frames 300] [--rounds 7] [--size 640x480] [--quality 80]

The frames are the simulated fisheye room view (the bench's front camera), encoded once by OpenCV at the headset
stream's quality and stripped of their DHT segments, as UVC cameras send them. Per frame, each way does what the
daemon's camera thread and HTTP pool do with one frame:

- ``forward``: the driver's buffer (one row of bytes, as OpenCV's V4L2 backend hands it over with
  ``CAP_PROP_CONVERT_RGB`` off) to ``bytes``, then ``with_huffman_tables`` (the front camera service's check);
- ``forward_with_tables``: ``with_huffman_tables`` of a frame that has them (the picamera2 VideoCore path and the
  bench board's preloaded JPEGs: a scan and no copy);
- ``software``: ``cv2.imdecode`` to BGR (what OpenCV's V4L2 backend does with MJPEG unless told not to) and the
  daemon's ``encode_jpeg`` at ``--quality`` (the headset stream's software path); ``software_decode_only``: the
  decode alone (the part ``feelium bench board`` never sees: its front camera hands over preloaded frames).

Rounds alternate the ways back to back; each round times ``--frames`` frames on the thread's CPU clock, and the
report is the median round, microseconds per frame, with ms/s at 15 fps and its projection onto a Pi Zero 2 W
core (docs/performance.md, *Projection onto the Pi*: 10x for Python-level work, 6x for OpenCV's codecs).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from collections.abc import Callable

import cv2
import numpy as np

from feelium.cameras.mjpeg import with_huffman_tables
from feelium.http.jpeg import encode_jpeg
from feelium.lab.daemon.preloaded import front_frames

FPS = 15.0
PI_FACTOR = {"forward": 10.0, "forward_with_tables": 10.0, "software": 6.0, "software_decode_only": 6.0}


def uvc_frames(size: tuple[int, int], quality: int, count: int) -> tuple[list[np.ndarray], list[bytes]]:
    """``count`` frames as a UVC camera's driver buffers (one row of uint8, no DHT) and as JPEGs with tables."""
    with_tables = [encode_jpeg(image, quality) for image in front_frames(size, FPS, count / FPS, seed=1)]
    buffers = []
    for data in with_tables:
        while (start := data.find(b"\xff\xc4", 2, data.find(b"\xff\xda"))) >= 0:
            data = data[:start] + data[start + 2 + (data[start + 2] << 8 | data[start + 3]) :]
        buffers.append(np.frombuffer(data, np.uint8).reshape(1, -1).copy())
    return buffers, with_tables


def timed(work: Callable[[int], object], frames: int, count: int) -> float:
    """Thread CPU microseconds per frame of ``work(i)`` over ``frames`` frames cycling through ``count`` inputs."""
    start = time.thread_time()
    for i in range(frames):
        work(i % count)
    return 1e6 * (time.thread_time() - start) / frames


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--quality", type=int, default=80)
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    cv2.setNumThreads(1)  # the codecs are single-threaded anyway; no pool spinning in the thread's figure
    buffers, with_tables = uvc_frames(size, args.quality, 15)  # type: ignore[arg-type]
    for i, buffer in enumerate(buffers):  # the inserted tables decode exactly as OpenCV's own
        fixed = np.frombuffer(with_huffman_tables(buffer.tobytes()), np.uint8)
        original = np.frombuffer(with_tables[i], np.uint8)
        assert np.array_equal(cv2.imdecode(fixed, cv2.IMREAD_COLOR), cv2.imdecode(original, cv2.IMREAD_COLOR))
    ways: dict[str, Callable[[int], object]] = {
        "forward": lambda i: with_huffman_tables(buffers[i].tobytes()),
        "forward_with_tables": lambda i: with_huffman_tables(with_tables[i]),
        "software": lambda i: encode_jpeg(cv2.imdecode(buffers[i], cv2.IMREAD_COLOR), args.quality),
        "software_decode_only": lambda i: cv2.imdecode(buffers[i], cv2.IMREAD_COLOR),
    }
    runs: dict[str, list[float]] = {way: [] for way in ways}
    for _ in range(args.rounds):
        for way, work in ways.items():
            runs[way].append(timed(work, args.frames, len(buffers)))
    report: dict[str, object] = {
        "size": list(size), "quality": args.quality, "frame_bytes_median": int(statistics.median(b.size for b in buffers)),
        "load_1min": round(os.getloadavg()[0], 2), "rounds": args.rounds, "frames_per_round": args.frames,
    }  # fmt: skip
    for way, figures in runs.items():
        us = statistics.median(figures)
        report[way] = {
            "us_per_frame": round(us, 1), "us_range": [round(min(figures), 1), round(max(figures), 1)],
            "ms_per_s_at_15fps": round(us * FPS / 1000, 3),
            "pi_cores_at_15fps": round(us * FPS * PI_FACTOR[way] / 1e6, 4),
        }  # fmt: skip
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
