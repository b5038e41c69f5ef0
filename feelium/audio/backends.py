"""Speaker and microphone behind small protocols: ALSA via ``aplay``/``arecord`` on the blimp, simulated (sim) elsewhere.

``aplay``/``arecord`` (alsa-utils, on every Raspberry Pi OS image) keep the
daemon free of a native audio binding: raw PCM goes through a pipe, the
kernel's pipe buffer plus ALSA's period buffer are the only queues, and a
crashed tool is just a process to restart. The sim devices keep real-time
pace on an absolute schedule (chunk k is due at start + k * duration), so
their timing never drifts however late the event loop runs.
"""

from __future__ import annotations

import asyncio
import math
import shutil
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import numpy as np


class Speaker(Protocol):
    async def start(self) -> None: ...

    async def write(self, pcm: bytes) -> None:
        """Hand PCM16 mono to the device; returns when the device has room for more."""

    async def close(self) -> None: ...


class Microphone(Protocol):
    async def start(self) -> None: ...

    async def read(self, n_bytes: int) -> bytes:
        """Exactly ``n_bytes`` of PCM16 mono (fewer only at end of stream)."""

    async def close(self) -> None: ...


ALSA_HINT = "sudo apt install alsa-utils (docs/deploy.md)"


def alsa_available() -> bool:
    """True when alsa-utils is installed and the kernel lists a sound card."""
    cards = Path("/proc/asound/cards")
    try:
        listed = cards.read_text().strip()
    except OSError:
        return False
    has_card = bool(listed) and "no soundcards" not in listed
    return has_card and shutil.which("aplay") is not None and shutil.which("arecord") is not None


def _pcm_args(rate: int) -> list[str]:
    return ["-q", "-t", "raw", "-f", "S16_LE", "-c", "1", "-r", str(rate)]


class _AlsaTool:
    """One ``aplay``/``arecord`` process on a raw PCM pipe: what the speaker and the microphone share."""

    program = ""

    def __init__(self, rate: int, device: str) -> None:
        self.rate = rate
        self.device = device
        self._proc: asyncio.subprocess.Process | None = None

    async def _spawn(self, *, stdin: int, stdout: int) -> None:
        """Start the tool; a missing one says what to install (health shows this line as the reason)."""
        try:
            self._proc = await asyncio.create_subprocess_exec(
                self.program, "-D", self.device, *_pcm_args(self.rate), stdin=stdin, stdout=stdout,
                stderr=asyncio.subprocess.PIPE,
            )  # fmt: skip
        except FileNotFoundError:
            raise FileNotFoundError(f"{self.program} is not installed: {ALSA_HINT}") from None

    async def close(self) -> None:
        await _end(self._proc)
        self._proc = None


class AlsaSpeaker(_AlsaTool):
    """``aplay`` reading raw PCM from a pipe."""

    program = "aplay"

    async def start(self) -> None:
        await self._spawn(stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.DEVNULL)

    async def write(self, pcm: bytes) -> None:
        proc = self._proc
        if proc is None or proc.stdin is None or proc.returncode is not None:
            raise RuntimeError("aplay is not running")
        proc.stdin.write(pcm)
        await proc.stdin.drain()


class AlsaMicrophone(_AlsaTool):
    """``arecord`` writing raw PCM to a pipe."""

    program = "arecord"

    async def start(self) -> None:
        await self._spawn(stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.PIPE)

    async def read(self, n_bytes: int) -> bytes:
        proc = self._proc
        if proc is None or proc.stdout is None:
            raise RuntimeError("arecord is not running")
        try:
            return await proc.stdout.readexactly(n_bytes)
        except asyncio.IncompleteReadError as exc:
            return exc.partial


async def _end(proc: asyncio.subprocess.Process | None, grace_s: float = 0.3) -> None:
    """Stop an ALSA tool: end of input first (``aplay`` plays out what it has), then SIGTERM, then SIGKILL."""
    if proc is None or proc.returncode is not None:
        return
    if proc.stdin is not None:
        proc.stdin.close()
        try:
            await asyncio.wait_for(proc.wait(), grace_s)
            return
        except asyncio.TimeoutError:
            pass
    proc.terminate()
    try:
        await asyncio.wait_for(proc.wait(), 0.3)
    except asyncio.TimeoutError:
        proc.kill()
        await proc.wait()


class SimSpeaker:
    """The simulated speaker: consumes audio at real-time pace and remembers the last ``keep_bytes`` it played."""

    def __init__(self, rate: int, clock: Callable[[], float] = time.monotonic, keep_bytes: int = 64000) -> None:
        self.rate = rate
        self.clock = clock
        self.played_bytes = 0
        self.recent: deque[bytes] = deque()
        self._recent_size = 0
        self._keep = keep_bytes
        self._busy_until: float | None = None

    async def start(self) -> None:
        self._busy_until = None

    async def write(self, pcm: bytes) -> None:
        now = self.clock()
        start = now if self._busy_until is None or self._busy_until < now else self._busy_until
        self._busy_until = start + len(pcm) / (2 * self.rate)
        self.played_bytes += len(pcm)
        self.recent.append(pcm)
        self._recent_size += len(pcm)
        while self._recent_size > self._keep and len(self.recent) > 1:
            self._recent_size -= len(self.recent.popleft())
        # like a device with a one-chunk buffer: accept the next write while this one plays
        await asyncio.sleep(max(0.0, start - now))

    async def close(self) -> None:
        pass


class SimMicrophone:
    """The simulated microphone: a continuous quiet tone (or silence) delivered in real time on an absolute schedule."""

    def __init__(self, rate: int, tone_hz: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.rate = rate
        self.tone_hz = tone_hz
        self.clock = clock
        self._t0: float | None = None
        self._samples = 0

    async def start(self) -> None:
        self._t0 = self.clock()
        self._samples = 0

    def _synth(self, n: int) -> bytes:
        if self.tone_hz <= 0:
            return bytes(2 * n)
        k = np.arange(self._samples, self._samples + n)
        wave = 3000.0 * np.sin(2 * math.pi * self.tone_hz * k / self.rate)
        return wave.astype("<i2").tobytes()

    async def read(self, n_bytes: int) -> bytes:
        if self._t0 is None:
            await self.start()
        assert self._t0 is not None
        n = n_bytes // 2
        due = self._t0 + (self._samples + n) / self.rate
        await asyncio.sleep(max(0.0, due - self.clock()))
        data = self._synth(n)
        self._samples += n
        return data

    async def close(self) -> None:
        pass
