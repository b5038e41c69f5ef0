"""JPEGs of a video slot, encoded once per published frame and shared by every client.

The Pi has four slow cores: encoding per client would multiply the cost by
the number of headsets and debug pages. A :class:`JpegFeed` encodes lazily
(only while someone asks), at most once per frame, in a worker thread, and
every client waiting for that frame gets the same bytes. A frame the camera's
hardware encoder already made (:class:`~feelium.cameras.base.Jpeg`, the blimp's
front camera) is forwarded as it is.
"""

from __future__ import annotations

import asyncio
from typing import Any

import cv2
import numpy as np

from feelium.cameras.base import Jpeg
from feelium.hub import Latest, Stamped


class FrameError(ValueError):
    """A published frame cannot be encoded (wrong type or shape)."""


def encode_jpeg(frame: Any, quality: int) -> bytes:
    """JPEG bytes of a gray or BGR ``uint8`` frame (other dtypes are clipped to 0..255)."""
    if not isinstance(frame, np.ndarray) or frame.ndim not in (2, 3) or frame.size == 0:
        raise FrameError(f"expected a gray or BGR image array, got {type(frame).__name__} {getattr(frame, 'shape', '')}")
    if frame.ndim == 3 and frame.shape[2] not in (1, 3, 4):
        raise FrameError(f"expected 1, 3 or 4 channels, got shape {frame.shape}")
    if frame.dtype != np.uint8:
        frame = np.clip(np.nan_to_num(frame), 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise FrameError(f"OpenCV could not encode a frame of shape {frame.shape}")
    return buf.tobytes()


class JpegFeed:
    """Newest-frame JPEGs of one :class:`~feelium.hub.Latest` slot."""

    def __init__(self, name: str, slot: Latest[Any], quality: int) -> None:
        self.name = name
        self.slot = slot
        self.quality = quality
        self._cached: Stamped[bytes] | None = None
        self._lock = asyncio.Lock()
        self.encoded = 0
        self.forwarded = 0  # frames that came already encoded (:class:`~feelium.cameras.base.Jpeg`)
        self.bad_frames = 0
        self.clients = 0

    async def _jpeg_of(self, item: Stamped[Any]) -> Stamped[bytes] | None:
        async with self._lock:
            cached = self._cached
            if cached is not None and cached.seq >= item.seq:
                return cached
            newest = self.slot.get() or item  # a newer frame may have arrived while we waited
            if isinstance(newest.value, Jpeg):  # the camera's hardware encoder made it: no thread, no work
                self.forwarded += 1
                self._cached = Stamped(newest.seq, newest.t, newest.value.data)
                return self._cached
            try:
                data = await asyncio.to_thread(encode_jpeg, newest.value, self.quality)
            except FrameError:
                self.bad_frames += 1
                return None
            self.encoded += 1
            self._cached = Stamped(newest.seq, newest.t, data)
            return self._cached

    async def newest(self) -> Stamped[bytes] | None:
        """The JPEG of the newest frame, or ``None`` when there is none (or it cannot be encoded)."""
        item = self.slot.get()
        return None if item is None else await self._jpeg_of(item)

    async def next_after(self, seq: int, timeout: float | None) -> Stamped[bytes] | None:
        """The JPEG of the newest frame newer than ``seq``; ``None`` on timeout."""
        item = await self.slot.next_after(seq, timeout)
        if item is None or item.seq <= seq:
            return None
        return await self._jpeg_of(item)

    def health(self) -> dict[str, int]:
        return {"clients": self.clients, "encoded": self.encoded, "forwarded": self.forwarded, "bad_frames": self.bad_frames}
