"""The ``[audio]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


@dataclass(frozen=True)
class AudioConfig:
    """Speech playback and capture on the blimp."""

    backend: Literal["auto", "alsa", "sim", "off"] = setting(
        "auto", "Audio device; auto is ALSA on a Raspberry Pi and the simulated speaker and microphone elsewhere."
    )
    sample_rate: int = setting(16000, "Sample rate of speech both ways (PCM16 mono); uploads at other rates are resampled.",
                               min=8000, max=48000)
    chunk_ms: int = setting(40, "Capture chunk length; also the playback write size.", min=10, max=500)
    max_playback_ms: int = setting(
        400, "Most wearer speech queued for the speaker; older audio is dropped so latency never grows.", min=40, max=5000
    )
    capture_keep_ms: int = setting(
        2000, "Blimp-to-wearer audio kept for the headset to fetch; a client further behind skips ahead.",
        min=100, max=30000,
    )
    playback_device: str = setting("default", "ALSA playback device (aplay -D).")
    capture_device: str = setting("default", "ALSA capture device (arecord -D).")
    sim_tone_hz: float = setting(
        440.0, "The simulated microphone's tone (0 = silence), so a browser can hear the link works.", min=0.0, max=4000.0
    )
