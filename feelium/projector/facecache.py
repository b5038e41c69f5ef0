"""The wearer's faces already decoded, by their JPEG bytes: a looping avatar's frames are decoded in its first two
rounds, not at every showing.

Why: a looping upload (``PUT /face`` with several frames, docs/api.md) plays the same JPEGs again and again, at 12
frames a second by default, and each showing was decoded and fitted to the canvas anew: ~2 ms of the shared pool
per frame here (decode 1.3, fit 0.8, and the page faults of two fresh 0.5 MB arrays), 20-25 ms of CPU a second in
``feelium bench board`` (docs/performance.md, session 17). Kept, each fitted face costs its canvas-sized array
(0.59 MB at 512x384), so a face is kept only the second time it is decoded (a loop came round: a stream of single
JPEGs, each shown once, keeps none), and at most ``max_bytes`` of them: faces that do not fit are decoded every
time, as before. Faces not shown for ``idle_s`` (an upload that stopped playing) are let go when the next face is
decoded, and all of them when the wearer clears the face: their memory goes back to the system (each is an mmap).

The faces handed out are read-only: the renderer takes "the same face array" for "the same picture" (it skips
redrawing), so an array shown again must never have been changed in place.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class _Entry:
    face: np.ndarray
    used: float  # the last time it was asked for (the caller's clock)


class DecodedFaces:
    """Fitted faces by the JPEG bytes they were decoded from, within a byte budget."""

    def __init__(self, max_bytes: int, idle_s: float = 5.0) -> None:
        self.max_bytes = max_bytes
        self.idle_s = idle_s
        self._entries: dict[bytes, _Entry] = {}
        self._sighted: dict[bytes, float] = {}  # JPEGs decoded once and not kept, with when
        self.bytes = 0
        self.misses = 0  # asked for a face not kept: decoded by the caller

    def get(self, jpeg: object, now: float) -> np.ndarray | None:
        """The face decoded from ``jpeg`` before, or None (also for anything that is not ``bytes``)."""
        entry = self._entries.get(jpeg) if isinstance(jpeg, bytes) else None
        if entry is None:
            self.misses += 1
            return None
        entry.used = now
        return entry.face

    def put(self, jpeg: object, face: np.ndarray, now: float) -> np.ndarray:
        """Keep ``face`` (decoded from ``jpeg``) if ``jpeg`` was decoded before and the face fits, after dropping
        what was unused for ``idle_s``; returns it, read-only either way (kept or not, the renderer may be handed it
        again only unchanged)."""
        face.flags.writeable = False
        for key in [k for k, e in self._entries.items() if now - e.used >= self.idle_s]:
            self.bytes -= self._entries.pop(key).face.nbytes
        for key in [k for k, t in self._sighted.items() if now - t >= self.idle_s]:
            del self._sighted[key]
        if not isinstance(jpeg, bytes) or jpeg in self._entries:
            return face
        if self._sighted.pop(jpeg, None) is None:
            self._sighted[jpeg] = now  # the first time: kept if it comes round again
            return face
        if self.bytes + face.nbytes <= self.max_bytes:
            self._entries[jpeg] = _Entry(face, now)
            self.bytes += face.nbytes
        return face

    def clear(self) -> None:
        """Let every kept face go (the wearer cleared the face)."""
        self._entries.clear()
        self._sighted.clear()
        self.bytes = 0

    def __len__(self) -> int:
        return len(self._entries)
