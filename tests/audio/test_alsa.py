"""The ALSA backends through stand-in ``aplay``/``arecord`` executables (no sound card needed).

The stand-ins record their arguments and move raw bytes exactly as the real
tools do through their pipes, so this checks the command lines, the PCM
plumbing, the end of a capture stream and the shutdown of the processes.
"""

from __future__ import annotations

import asyncio
import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from feelium.audio.backends import AlsaMicrophone, AlsaSpeaker
from feelium.events import SpeechOut
from feelium.audio.config import AudioConfig
from feelium.audio.service import AudioService
from feelium.daemon.assembly import build_audio
from feelium.daemon.config import Config
from feelium.hub import Hub

CAPTURED_BYTES = 3200  # what the stand-in arecord delivers before its stream ends


@pytest.fixture
def alsa_tools(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """``aplay`` copies stdin to a file; ``arecord`` writes a ramp of samples then exits."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "aplay").write_text(f'#!/bin/sh\necho "$@" > {tmp_path}/aplay.args\nexec cat > {tmp_path}/played.raw\n')
    ramp = tmp_path / "ramp.raw"
    ramp.write_bytes(np.arange(CAPTURED_BYTES // 2, dtype="<i2").tobytes())
    (bin_dir / "arecord").write_text(f'#!/bin/sh\necho "$@" > {tmp_path}/arecord.args\nexec cat {ramp}\n')
    for tool in ("aplay", "arecord"):
        (bin_dir / tool).chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    return tmp_path


async def test_speaker_pipes_raw_pcm16_mono_to_aplay_on_the_device(alsa_tools: Path) -> None:
    speaker = AlsaSpeaker(16000, "plughw:1,0")
    await speaker.start()
    await speaker.write(b"\x01\x02" * 500)
    await speaker.write(b"\x03\x04" * 10)
    await speaker.close()
    for _ in range(100):  # the stand-in flushes its file when cat sees the pipe close
        if (alsa_tools / "played.raw").exists() and (alsa_tools / "played.raw").stat().st_size == 1020:
            break
        await asyncio.sleep(0.01)
    assert (alsa_tools / "played.raw").read_bytes() == b"\x01\x02" * 500 + b"\x03\x04" * 10
    assert (alsa_tools / "aplay.args").read_text().split() == [
        "-D", "plughw:1,0", "-q", "-t", "raw", "-f", "S16_LE", "-c", "1", "-r", "16000",
    ]  # fmt: skip
    with pytest.raises(RuntimeError, match="aplay is not running"):
        await speaker.write(b"\x00\x00")


async def test_microphone_reads_exact_chunks_then_reports_the_end(alsa_tools: Path) -> None:
    mic = AlsaMicrophone(8000, "default")
    await mic.start()
    first = await mic.read(1000)
    rest = await mic.read(CAPTURED_BYTES)  # only 2200 bytes remain: the partial tail, then nothing
    assert np.array_equal(np.frombuffer(first + rest, "<i2"), np.arange(CAPTURED_BYTES // 2))
    assert await mic.read(100) == b""
    await mic.close()
    assert "-r 8000" in (alsa_tools / "arecord.args").read_text()


async def test_service_on_alsa_publishes_captured_chunks_and_fails_loudly_when_capture_ends(alsa_tools: Path) -> None:
    hub = Hub()
    cfg = replace(AudioConfig(), backend="alsa", sample_rate=8000, chunk_ms=50)  # 800-byte chunks
    service = build_audio(replace(Config(), audio=cfg), hub)
    assert isinstance(service, AudioService) and service.health()["backend"] == "alsa"
    captured = hub.bus.subscribe([SpeechOut], maxsize=16)
    task = asyncio.create_task(service.run())
    with pytest.raises(ExceptionGroup) as failure:  # the supervisor restarts a service whose device stream ended
        await asyncio.wait_for(task, 5)
    assert failure.group_contains(RuntimeError, match="microphone stream ended")
    chunks = captured.drain()
    assert [len(c.pcm) for c in chunks] == [800] * (CAPTURED_BYTES // 800)
    assert service.captured_chunks == CAPTURED_BYTES // 800
