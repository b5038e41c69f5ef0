"""The audio service: plays the wearer's speech in the room and captures the room for the wearer."""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import numpy as np

from feelium.audio.backends import Microphone, Speaker
from feelium.audio.buffer import PlaybackBuffer
from feelium.events import SpeechIn, SpeechOut
from feelium.audio.config import AudioConfig
from feelium.wav import resample
from feelium.hub import Hub

log = logging.getLogger(__name__)


class AudioService:
    """Wearer speech from the bus to the speaker; microphone chunks onto the bus."""

    name = "audio"
    stop_order = 50

    def __init__(self, config: AudioConfig, hub: Hub, speaker: Speaker, microphone: Microphone, backend: str) -> None:
        self.config = config
        self.hub = hub
        self.speaker = speaker
        self.microphone = microphone
        self.backend = backend
        self.buffer = PlaybackBuffer(config.sample_rate, config.max_playback_ms)
        self.chunk_bytes = 2 * config.sample_rate * config.chunk_ms // 1000
        self.received_chunks = 0
        self.bad_chunks = 0
        self.captured_chunks = 0
        self._wake = asyncio.Event()

    async def run(self) -> None:
        sub = self.hub.bus.subscribe([SpeechIn], maxsize=64)
        try:
            await self.speaker.start()
            await self.microphone.start()
            async with asyncio.TaskGroup() as group:
                group.create_task(self._receive(sub))
                group.create_task(self._play())
                group.create_task(self._capture())
        finally:
            sub.close()
            await self.speaker.close()
            await self.microphone.close()

    def accept(self, chunk: SpeechIn) -> None:
        """Queue one wearer chunk for the speaker (resampled to the device rate); bad ones are counted."""
        if chunk.rate <= 0 or len(chunk.pcm) % 2:
            self.bad_chunks += 1
            return
        samples = np.frombuffer(chunk.pcm, dtype="<i2")
        self.buffer.push(resample(samples, chunk.rate, self.config.sample_rate).astype("<i2").tobytes())
        self.received_chunks += 1
        self._wake.set()

    async def _receive(self, sub: Any) -> None:
        while True:
            chunk = await sub.get()
            if chunk is not None:
                self.accept(chunk)

    async def _play(self) -> None:
        while True:
            pcm = self.buffer.pop(self.chunk_bytes)
            if not pcm:
                self._wake.clear()
                await self._wake.wait()
                continue
            await self.speaker.write(pcm)

    async def _capture(self) -> None:
        while True:
            pcm = await self.microphone.read(self.chunk_bytes)
            if not pcm:
                raise RuntimeError("the microphone stream ended")
            self.captured_chunks += 1
            self.hub.bus.publish(SpeechOut(pcm, self.config.sample_rate, self.hub.clock()))

    async def stop(self) -> None:
        self._wake.set()

    def health(self) -> dict[str, Any]:
        return {
            "backend": self.backend,
            "received_chunks": self.received_chunks,
            "bad_chunks": self.bad_chunks,
            "captured_chunks": self.captured_chunks,
            "playback_buffered_ms": round(self.buffer.buffered_ms, 1),
            "playback_dropped_ms": round(1000.0 * self.buffer.dropped_bytes / (2 * self.config.sample_rate), 1),
        }
