"""Speech: WAV coding, resampling, the bounded speaker queue, and the service with sim devices."""

from __future__ import annotations

import asyncio
import io
import wave
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.audio.backends import SimMicrophone, SimSpeaker
from feelium.audio.buffer import PlaybackBuffer
from feelium.events import SpeechIn, SpeechOut
from feelium.audio.config import AudioConfig
from feelium.audio.service import AudioService
from feelium.daemon.assembly import build_audio
from feelium.wav import WavError, decode_wav, encode_wav, resample
from feelium.daemon.config import Config
from feelium.hub import Hub


def test_wav_round_trip_and_stereo_downmix() -> None:
    samples = np.arange(-500, 500, dtype="<i2")
    decoded, rate = decode_wav(encode_wav(samples.tobytes(), 22050))
    assert rate == 22050 and np.array_equal(decoded, samples)
    stereo = np.stack([samples, np.zeros_like(samples)], axis=1)
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(2)
        w.setframerate(16000)
        w.writeframes(stereo.tobytes())
    mono, _ = decode_wav(buf.getvalue())
    assert np.array_equal(mono, (samples.astype(np.int32) / 2).astype(np.int16))  # mean, truncated toward zero


@pytest.mark.parametrize("data, fragment", [(b"", "not a PCM WAV"), (b"RIFF\x00\x00\x00\x00WAVE", "not a PCM WAV")])
def test_decode_wav_names_the_problem(data: bytes, fragment: str) -> None:
    with pytest.raises(WavError, match=fragment):
        decode_wav(data)


def test_resample_keeps_duration_and_a_tone() -> None:
    t = np.arange(8000) / 8000
    tone = (10000 * np.sin(2 * np.pi * 300 * t)).astype(np.int16)
    up = resample(tone, 8000, 16000)
    assert up.size == 16000
    spectrum = np.abs(np.fft.rfft(up.astype(float)))
    assert abs(np.argmax(spectrum) * 16000 / up.size - 300) < 2


@given(chunks=st.lists(st.integers(0, 3000), max_size=40), pops=st.lists(st.integers(0, 4000), max_size=40))
def test_playback_buffer_is_bounded_and_loses_only_counted_bytes(chunks: list[int], pops: list[int]) -> None:
    buf = PlaybackBuffer(rate=8000, max_ms=100)  # 1600 bytes
    pushed = popped = 0
    for i, n in enumerate(chunks):
        buf.push(bytes(n))
        pushed += n - n % 2
        assert len(buf) <= max(buf.max_bytes, n - n % 2)  # the backlog: max_ms, or the one newest chunk
        if i < len(pops):
            popped += len(buf.pop(pops[i]))
    assert pushed == popped + len(buf) + buf.dropped_bytes
    assert len(buf) % 2 == 0


def test_playback_buffer_keeps_the_newest_audio() -> None:
    buf = PlaybackBuffer(rate=1000, max_ms=4)  # 8 bytes
    buf.push(b"aabb")
    buf.push(b"ccddee")
    assert buf.pop(100) == b"bbccddee"
    assert buf.dropped_bytes == 2


def test_a_chunk_longer_than_the_bound_is_played_whole_and_replaces_the_backlog() -> None:
    buf = PlaybackBuffer(rate=1000, max_ms=4)  # 8 bytes
    buf.push(b"aabb")
    buf.push(b"0123456789")  # longer than the bound: kept whole, the older audio goes
    assert buf.pop(100) == b"0123456789"
    assert buf.dropped_bytes == 4


class ManualClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


async def test_sim_microphone_keeps_an_absolute_schedule() -> None:
    clock = ManualClock()
    mic = SimMicrophone(rate=1000, tone_hz=100.0, clock=clock)
    await mic.start()
    clock.now = 5.0  # the loop ran late: chunks due long ago come at once, none is skipped or stretched
    chunks = [await asyncio.wait_for(mic.read(200), 0.5) for _ in range(10)]
    samples = np.frombuffer(b"".join(chunks), "<i2")
    assert samples.size == 1000
    expected = (3000 * np.sin(2 * np.pi * 100 * np.arange(1000) / 1000)).astype("<i2")
    assert np.array_equal(samples, expected)  # continuous phase across chunks


async def test_service_plays_wearer_speech_and_publishes_room_audio() -> None:
    hub = Hub()
    cfg = replace(AudioConfig(), sample_rate=8000, chunk_ms=20, max_playback_ms=200)
    speaker = SimSpeaker(8000)
    service = AudioService(cfg, hub, speaker, SimMicrophone(8000, 0.0), "sim")
    out = hub.bus.subscribe([SpeechOut])
    task = asyncio.create_task(service.run())
    await asyncio.sleep(0.01)
    hub.bus.publish(SpeechIn(b"\x01\x00" * 800, 8000, 0.0))  # 100 ms
    chunk = await out.get(timeout=2)
    assert chunk is not None and chunk.rate == 8000 and len(chunk.pcm) == 320
    for _ in range(100):
        if speaker.played_bytes >= 1600:
            break
        await asyncio.sleep(0.01)
    assert speaker.played_bytes == 1600
    hub.bus.publish(SpeechIn(b"\x01", 8000, 0.0))  # odd length: not PCM16
    await asyncio.sleep(0.02)
    assert service.health()["bad_chunks"] == 1
    await service.stop()
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


def test_accept_resamples_to_the_device_rate() -> None:
    hub = Hub()
    service = AudioService(replace(AudioConfig(), sample_rate=16000), hub, SimSpeaker(16000), SimMicrophone(16000, 0), "sim")
    service.accept(SpeechIn(b"\x00\x01" * 100, 8000, 0.0))
    assert len(service.buffer) == 400


def test_build_audio_respects_off_and_falls_back_to_sim() -> None:
    assert build_audio(replace(Config(), audio=replace(AudioConfig(), backend="off")), Hub()) is None
    service = build_audio(replace(Config(), audio=replace(AudioConfig(), backend="sim")), Hub())
    assert service.health()["backend"] == "sim"
