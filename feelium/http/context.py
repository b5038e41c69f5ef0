"""What the handlers share: the config, the hub, the feeds and the link's counters."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from aiohttp import web

from feelium.http.auth import TokenStore
from feelium.http.config import HttpConfig
from feelium.http.face import FacePlayer
from feelium.http.feed import EventFeed
from feelium.http.jpeg import JpegFeed
from feelium.http.lease import ControlLease
from feelium.http.pairing import PairingCodes
from feelium.http.ratelimit import ClientBuckets
from feelium.http.open_streams import OpenStreams
from feelium.http.slots import StreamSlots
from feelium.http.speech import SpeechFeed
from feelium.hub import Hub


@dataclass(frozen=True)
class SpeechSettings:
    """What the link needs of ``[audio]``: the PCM rate both ways and how much room sound to keep for a late poll.

    Passed in by the daemon's assembly (``SpeechSettings.from_audio(config.audio)``) so the link does not
    import the audio service's package; the defaults are ``[audio]``'s.
    """

    sample_rate: int = 16000
    capture_keep_ms: int = 2000

    @classmethod
    def from_audio(cls, audio: Any) -> "SpeechSettings":
        """From an ``[audio]`` section (anything with ``sample_rate`` and ``capture_keep_ms``)."""
        return cls(sample_rate=int(audio.sample_rate), capture_keep_ms=int(audio.capture_keep_ms))


@dataclass
class LinkContext:
    config: HttpConfig
    speech_settings: SpeechSettings
    hub: Hub
    tokens: TokenStore  # the bearer token in force (follows a rotated token file)
    pairing: PairingCodes  # short codes a headset exchanges for the token
    events: EventFeed
    speech: SpeechFeed
    videos: dict[str, JpegFeed]
    face: FacePlayer
    motion_limit: ClientBuckets  # per client; stop is never charged
    action_limit: ClientBuckets  # wearer actions and face uploads, per client
    speech_limit: ClientBuckets
    lease: ControlLease  # who may steer
    streams: StreamSlots  # MJPEG streams per client and in total
    speech_streams: StreamSlots  # GET /speech/stream per client and in total
    event_streams: StreamSlots  # GET /events/ws and /events/stream per client and in total
    open_streams: OpenStreams  # every long-lived stream with its token, closed when the token is rotated away
    counters: dict[str, int] = field(default_factory=dict)
    wall_clock: Callable[[], float] = time.time  # only for GET /clock: every other time is hub.clock
    last_request_at: float | None = None
    last_motion_at: float | None = None
    uploads_in_flight: int = 0  # face bodies being read now ([http] max_uploads_in_flight)

    def count(self, name: str, n: int = 1) -> None:
        self.counters[name] = self.counters.get(name, 0) + n

    def link_state(self, now: float) -> dict[str, Any]:
        """How alive the headset link looks from the blimp (for ``/state``)."""
        def age(t: float | None) -> float | None:
            return None if t is None else round(now - t, 3)

        return {
            "last_request_age_s": age(self.last_request_at),
            "last_motion_age_s": age(self.last_motion_at),
            "controller": holder.client if (holder := self.lease.holder(now)) is not None else None,
            "video_clients": sum(f.clients for f in self.videos.values()),
            "event_clients": self.counters.get("event_clients", 0),
            "speech_clients": self.speech_streams.in_use,
        }


CONTEXT: web.AppKey[LinkContext] = web.AppKey("feelium_link", LinkContext)


def ctx(request: web.Request) -> LinkContext:
    return request.app[CONTEXT]
