"""PCM16 WAV chunks: the speech format of the headset link.

WAV is self-describing (rate, channels, sample width in a 44-byte header),
plays in every browser's ``<audio>`` and AVFoundation without a codec, and
costs no CPU to encode on the Pi; at 16 kHz mono it is 32 kB/s, small next
to the video. Pure functions over bytes and arrays.
"""

from __future__ import annotations

import io
import wave

import numpy as np


class WavError(ValueError):
    """A speech upload is not a PCM16 WAV we can play; says what is wrong."""


def encode_wav(pcm: bytes, rate: int, channels: int = 1) -> bytes:
    """A WAV file of PCM16 little-endian samples."""
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(channels)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(pcm)
    return buf.getvalue()


def decode_wav(data: bytes) -> tuple[np.ndarray, int]:
    """Mono int16 samples and the rate of a PCM16 WAV (stereo is averaged to mono)."""
    try:
        with wave.open(io.BytesIO(data), "rb") as w:
            channels, width, rate, frames = w.getnchannels(), w.getsampwidth(), w.getframerate(), w.getnframes()
            raw = w.readframes(frames)
    except (wave.Error, EOFError) as exc:
        raise WavError(f"not a PCM WAV file: {exc}") from exc
    if width != 2:
        raise WavError(f"expected 16-bit samples, got {8 * width}-bit")
    if not 1 <= channels <= 2:
        raise WavError(f"expected mono or stereo, got {channels} channels")
    if not 4000 <= rate <= 96000:
        raise WavError(f"sample rate {rate} Hz is outside 4000..96000")
    samples = np.frombuffer(raw[: len(raw) - len(raw) % (2 * channels)], dtype="<i2")
    if channels == 2:
        samples = samples.reshape(-1, 2).astype(np.int32).mean(axis=1).astype(np.int16)
    return samples.astype(np.int16, copy=False), rate


def resample(samples: np.ndarray, rate_in: int, rate_out: int) -> np.ndarray:
    """Linear-interpolation resampling of int16 speech (adequate for voice; no new dependency)."""
    if rate_in == rate_out or samples.size == 0:
        return samples.astype(np.int16, copy=False)
    n_out = max(1, round(samples.size * rate_out / rate_in))
    positions = np.arange(n_out) * (rate_in / rate_out)
    out = np.interp(positions, np.arange(samples.size), samples.astype(np.float64))
    return np.clip(np.round(out), -32768, 32767).astype(np.int16)
