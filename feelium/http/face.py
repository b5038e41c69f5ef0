"""The wearer's face or avatar for the projector: one JPEG, or a short loop played at a fixed rate.

Newest wins: a new upload replaces whatever was showing, and a loop is played
on an absolute schedule (frame k at start + k / fps) so it never drifts. What
is shown stays until replaced or cleared: a headset that uploads once (a still
Persona) must not see its face vanish while it is quiet.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Sequence

from feelium.hub import Hub
from feelium.jpeginfo import JpegHeaderError, jpeg_size


class JpegError(ValueError):
    """An upload is not a complete JPEG."""


class ImageTooLarge(JpegError):
    """A JPEG declares more pixels than the configured limit."""


def check_jpeg(data: bytes, max_pixels: int, what: str = "body") -> tuple[int, int]:
    """Cheap structural check (no decode on the Pi): SOI at the start, EOI at the end, a frame size within
    ``max_pixels`` read from the header. Returns ``(width, height)``."""
    if len(data) < 4 or not data.startswith(b"\xff\xd8\xff"):
        raise JpegError(f"{what} is not a JPEG (it must start with the FF D8 FF marker)")
    if not data.rstrip(b"\x00").endswith(b"\xff\xd9"):
        raise JpegError(f"{what} is a truncated JPEG (no FF D9 end marker)")
    try:
        width, height = jpeg_size(data)
    except JpegHeaderError as exc:
        raise JpegError(f"{what}: {exc}") from None
    if width * height > max_pixels:
        raise ImageTooLarge(
            f"{what} is {width}x{height} = {width * height} pixels; at most {max_pixels} are accepted "
            "([http] max_face_pixels): scale it down before sending"
        )
    return width, height


class FacePlayer:
    """Publishes uploads to ``hub.face``; loops multi-frame avatars until replaced."""

    def __init__(self, hub: Hub) -> None:
        self.hub = hub
        self._loop_task: asyncio.Task[None] | None = None

    def show(self, frames: Sequence[bytes], fps: float) -> None:
        """Show one frame, or loop several at ``fps``; replaces what was showing."""
        if not frames:
            raise ValueError("no frames")
        self.stop()
        self.hub.face.publish(self.hub.clock(), frames[0])
        if len(frames) > 1:
            self._loop_task = asyncio.get_running_loop().create_task(self._play(list(frames), fps))

    async def _play(self, frames: list[bytes], fps: float) -> None:
        loop = asyncio.get_running_loop()
        start = loop.time()
        k = 1
        while True:
            await asyncio.sleep(max(0.0, start + k / fps - loop.time()))
            self.hub.face.publish(self.hub.clock(), frames[k % len(frames)])
            k += 1

    def clear(self) -> None:
        """Stop showing the wearer's face: the projector returns to its default avatar (``None`` in ``hub.face``)."""
        self.stop()
        self.hub.face.publish(self.hub.clock(), None)

    def stop(self) -> None:
        if self._loop_task is not None:
            self._loop_task.cancel()
            self._loop_task = None

    async def close(self) -> None:
        task = self._loop_task
        self.stop()
        if task is not None:
            with contextlib.suppress(asyncio.CancelledError):
                await task
