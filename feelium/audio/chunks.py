"""Speech on the bus: wearer-to-blimp chunks for the speaker, blimp-to-wearer chunks for the headset.

Audio travels as bounded bus items like every other event, so the HTTP link
and the audio device never call each other and a slow side only loses audio.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SpeechIn:
    """Wearer speech to play in the room: PCM16 mono little-endian at ``rate``."""

    pcm: bytes
    rate: int
    t: float


@dataclass(frozen=True)
class SpeechOut:
    """Room sound captured on the blimp for the wearer: PCM16 mono little-endian at ``rate``."""

    pcm: bytes
    rate: int
    t: float
