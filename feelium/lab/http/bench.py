"""``feelium bench link`` (alias ``bench http``): motion round trip, `stop` under a flood, touch-event latency per
transport, MJPEG rate with a stalled client, speech delay and jitter streamed vs long-polled, and (unless
``--no-abuse``) the daemon's memory under hostile clients (``feelium.lab.http.abuse``).

The server runs on its own thread and event loop (as in the daemon), the
clients on this one, both on 127.0.0.1; every number has a baseline measured
in the same run: the plain ``/health`` round trip for motion, the in-process
bus delivery for events, three readers without a stalled client for MJPEG.
Times are ``time.perf_counter`` on both sides (one process, one clock).
"""

from __future__ import annotations

import asyncio
import json
import socket
import sys
import threading
import time
from collections import Counter
from dataclasses import replace
from typing import Any

import aiohttp
import cv2
import numpy as np
from aiohttp import web

from feelium.events import SpeechOut, TouchEvent
from feelium.http.app import create_app, link_of
from feelium.http.config import HttpConfig
from feelium.http.server import JsonErrorAppRunner
from feelium.http.speech_stream import decode_frame
from feelium.http.video import BOUNDARY
from feelium.hub import Hub
from feelium.motion import DEFAULT_HOLD_S, DeadManCommands, MotionCommand
from feelium.lab.http.abuse import format_abuse, run_abuse
from feelium.lab.report import emit_report

TOKEN = "bench-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


def summary(values_s: list[float]) -> dict[str, float]:
    """Median and p95 in milliseconds."""
    ms = np.asarray(values_s) * 1000.0
    return {"n": int(ms.size), "median_ms": round(float(np.median(ms)), 3), "p95_ms": round(float(np.percentile(ms, 95)), 3)}


class TimedMotion(DeadManCommands):
    """The hub's dead-man slot, noting when each command lands (what the flight loop would then read)."""

    def __init__(self) -> None:
        super().__init__()
        self.applied: list[tuple[str, float]] = []

    def command(self, name: str, now: float, hold_s: float = DEFAULT_HOLD_S, source: str = "headset") -> MotionCommand:
        cmd = super().command(name, now, hold_s, source)
        self.applied.append((name, time.perf_counter()))
        return cmd


class ServerThread:
    """The headset app with its own hub, on a private loop in a thread."""

    def __init__(self, config: HttpConfig) -> None:
        self.config = config
        self.loop = asyncio.new_event_loop()
        self.ready = threading.Event()
        self.port = 0
        self.hub: Hub | None = None
        self.motion = TimedMotion()
        self.app: web.Application | None = None
        self._thread = threading.Thread(target=self._main, daemon=True)
        self._stop: asyncio.Event | None = None

    def _main(self) -> None:
        asyncio.set_event_loop(self.loop)
        self.loop.run_until_complete(self._serve())

    async def _serve(self) -> None:
        self.hub = Hub(clock=time.perf_counter, motion=self.motion)
        self.app = create_app(self.config, self.hub, TOKEN)
        runner = JsonErrorAppRunner(self.app, access_log=None, shutdown_timeout=0.1)
        await runner.setup()
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        await web.TCPSite(runner, "127.0.0.1", self.port).start()
        self._stop = asyncio.Event()
        self.ready.set()
        await self._stop.wait()
        await runner.cleanup()

    def __enter__(self) -> "ServerThread":
        self._thread.start()
        if not self.ready.wait(10):
            raise RuntimeError("the bench server did not start")
        return self

    def __exit__(self, *exc: object) -> None:
        self.loop.call_soon_threadsafe(self._stop.set)  # type: ignore[union-attr]
        self._thread.join(5)

    def call(self, fn: Any, *args: Any) -> None:
        """Run ``fn(*args)`` on the server's loop (the hub is not thread-safe)."""
        self.loop.call_soon_threadsafe(fn, *args)

    @property
    def api(self) -> str:
        return f"http://127.0.0.1:{self.port}/api/v1"


async def bench_motion(server: ServerThread, n: int) -> dict[str, Any]:
    """POST /motion: request sent -> command in force on the hub, and the full round trip; /health as baseline."""
    motion_slot = server.motion
    names = ("forward", "turn_left", "up", "backward", "turn_right", "down")
    async with aiohttp.ClientSession(headers=AUTH) as session:
        async def timed(method: str, path: str, **kw: Any) -> tuple[float, float]:
            t0 = time.perf_counter()
            async with session.request(method, server.api + path, **kw) as resp:
                await resp.read()
                if resp.status >= 400:
                    raise RuntimeError(f"{method} {path}: {resp.status}")
            return t0, time.perf_counter()

        for i in range(20):  # warm the connection and the code paths
            await timed("GET", "/health")
            await timed("POST", "/motion", json={"command": names[i % len(names)], "hold_ms": 500})
        health, motion, visible = [], [], []
        for i in range(n):
            t0, t1 = await timed("GET", "/health")
            health.append(t1 - t0)
            name = names[i % len(names)]
            before = len(motion_slot.applied)
            t0, t1 = await timed("POST", "/motion", json={"command": name, "hold_ms": 500})
            landed = motion_slot.applied[before:]
            if len(landed) != 1 or landed[0][0] != name:
                raise RuntimeError(f"POST /motion {name}: the hub saw {landed}")
            motion.append(t1 - t0)
            visible.append(landed[0][1] - t0)
    base, mot, vis = summary(health), summary(motion), summary(visible)
    return {
        "baseline_health": base,
        "motion": mot,
        "sent_to_hub": vis,
        "ratio_median": round(mot["median_ms"] / base["median_ms"], 2),
    }


FLOOD_TASKS = 8  # concurrent requests the flooding client keeps in flight


async def bench_stop_under_flood(n: int) -> dict[str, Any]:
    """`stop` sent -> in force on the hub, with the shipped rate limits, quiet and while one client floods.

    The flooder keeps ``FLOOD_TASKS`` motion requests in flight (far past its bucket: most get 429, and 409
    once a bystander's stop has taken the lease). Its stops and a bystander's are timed the same way as the
    quiet baseline; every one of them must be accepted (200) and land on the hub.
    """
    with ServerThread(HttpConfig()) as server:
        slot = server.motion
        async with aiohttp.ClientSession(headers=AUTH, connector=aiohttp.TCPConnector(limit=0)) as session:

            async def post(client: str, command: str) -> tuple[int, float]:
                t0 = time.perf_counter()
                async with session.post(server.api + "/motion", json={"command": command, "hold_ms": 500},
                                        headers={"X-Feelium-Client": client}) as resp:  # fmt: skip
                    await resp.read()
                    return resp.status, t0

            async def timed_stops(client: str) -> dict[str, Any]:
                delays, refused = [], 0
                for _ in range(n):
                    before = len(slot.applied)
                    status, t0 = await post(client, "stop")
                    landed = [t for name, t in slot.applied[before:] if name == "stop"]
                    if status != 200 or not landed:
                        refused += 1
                    else:
                        delays.append(landed[0] - t0)
                    await asyncio.sleep(0.01)
                return summary(delays) | {"refused": refused}

            quiet = await timed_stops("bystander")
            flooding = asyncio.Event()
            statuses: Counter[int] = Counter()
            t_flood = time.perf_counter()

            async def flood() -> None:
                while not flooding.is_set():
                    status, _ = await post("flooder", "forward")
                    statuses[status] += 1

            tasks = [asyncio.create_task(flood()) for _ in range(FLOOD_TASKS)]
            await asyncio.sleep(0.3)  # the flooder's bucket is empty by now
            bystander = await timed_stops("bystander")
            own = await timed_stops("flooder")
            flooding.set()
            await asyncio.gather(*tasks)
            flood_s = time.perf_counter() - t_flood
    flood_total = sum(statuses.values())
    return {
        "quiet": quiet,
        "bystander_during_flood": bystander,
        "flooder_own_stop": own,
        "flood_requests_per_s": round(flood_total / flood_s, 1),
        "flood_statuses": {str(k): v for k, v in sorted(statuses.items())},
        "ratio_median_bystander_vs_quiet": round(bystander["median_ms"] / quiet["median_ms"], 2),
    }


def _touch(i: int, sent: float) -> TouchEvent:
    return TouchEvent(i, "down", None, sent, 320.0, 240.0, 0.5, 0.5, 0.4, 100, 0.9, extra={"sent": sent})


async def _publish_series(server: ServerThread, n: int, gap: float) -> None:
    hub = server.hub
    assert hub is not None
    for i in range(n):
        await asyncio.sleep(gap)
        server.call(lambda i=i: hub.bus.publish(_touch(i, time.perf_counter())))


async def bench_events(server: ServerThread, n: int, gap: float = 0.02) -> dict[str, Any]:
    """Publish ``n`` touches on the server's bus; each transport's client notes when each arrives."""
    hub = server.hub
    assert hub is not None
    results: dict[str, Any] = {}

    # baseline: a bus subscriber on the server loop itself (no HTTP)
    bus_lat: list[float] = []
    done = threading.Event()

    async def bus_listener() -> None:
        sub = hub.bus.subscribe([TouchEvent], maxsize=n + 8)
        while len(bus_lat) < n:
            ev = await sub.get()
            bus_lat.append(time.perf_counter() - ev.extra["sent"])
        sub.close()
        done.set()

    asyncio.run_coroutine_threadsafe(bus_listener(), server.loop)
    await asyncio.sleep(0.05)
    await _publish_series(server, n, gap)
    await asyncio.to_thread(done.wait, 10)
    results["baseline_bus"] = summary(bus_lat)

    async with aiohttp.ClientSession(headers=AUTH) as session:
        async def last_seq() -> int:
            async with session.get(server.api + "/events", params={"timeout": 0}) as resp:
                return int((await resp.json())["last_seq"])

        async def collect(kind: str) -> list[float]:
            lat: list[float] = []
            after = await last_seq()

            def note(item: dict[str, Any]) -> None:
                if item["type"] == "touch":
                    lat.append(time.perf_counter() - item["event"]["sent"])

            async def reader() -> None:
                nonlocal after
                if kind == "long_poll":
                    while len(lat) < n:
                        async with session.get(server.api + "/events", params={"after": after, "timeout": 1}) as resp:
                            body = await resp.json()
                        for item in body["events"]:
                            note(item)
                        after = body["last_seq"]
                elif kind == "sse":
                    async with session.get(server.api + "/events/stream", params={"after": after}) as resp:
                        async for raw in resp.content:
                            if raw.startswith(b"data: "):
                                note(json.loads(raw[6:]))
                                if len(lat) >= n:
                                    return
                else:
                    async with session.ws_connect(server.api.replace("http", "ws", 1) + f"/events/ws?after={after}") as ws:
                        async for msg in ws:
                            note(json.loads(msg.data))
                            if len(lat) >= n:
                                return

            task = asyncio.create_task(reader())
            await asyncio.sleep(0.1)
            await _publish_series(server, n, gap)
            await asyncio.wait_for(task, 30)
            return lat

        for kind in ("long_poll", "sse", "websocket"):
            s = summary(await collect(kind))
            s["ratio_median_vs_bus"] = round(s["median_ms"] / max(results["baseline_bus"]["median_ms"], 1e-6), 1)
            results[kind] = s
    return results


def _small_receive_buffer(addr_info: Any) -> socket.socket:
    """A client socket with a receive buffer like a phone's on Wi-Fi, not the megabytes Linux gives loopback."""
    family, type_, proto, _, _ = addr_info
    sock = socket.socket(family, type_, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, READER_RCVBUF_BYTES)
    return sock


async def _mjpeg_reader(api: str, seconds: float, client: str, pause_s: float = 0.0) -> list[tuple[float, float]]:
    """(arrival time, capture time) of each frame one client reads in ``seconds``, pausing ``pause_s`` after each.

    ``client`` is the reader's ``X-Feelium-Client`` id: each reader is its own client, as separate headsets
    are, so the per-client stream limit does not apply across readers.

    A pausing (slow) reader keeps its own buffers small (socket and aiohttp
    reader), as a headset that decodes the newest frame should: the age of
    its frames then measures what the server queued, not what it hoarded.
    """
    frames: list[tuple[float, float]] = []
    small = {"connector": aiohttp.TCPConnector(socket_factory=_small_receive_buffer), "read_bufsize": READER_RCVBUF_BYTES}
    headers = AUTH | {"X-Feelium-Client": client}
    async with aiohttp.ClientSession(headers=headers, **(small if pause_s else {})) as session:  # type: ignore[arg-type]
        async with session.get(api + "/video/front.mjpeg") as resp:
            t0 = time.perf_counter()
            while time.perf_counter() - t0 < seconds:
                try:
                    line = await resp.content.readline()
                except aiohttp.ClientPayloadError:  # the server dropped this reader as stalled
                    frames.append((float("nan"), float("nan")))
                    break
                if line == f"--{BOUNDARY}\r\n".encode():
                    length, stamp = 0, float("nan")
                    while (h := await resp.content.readline()) != b"\r\n":
                        name, _, value = h.partition(b":")
                        if name.lower() == b"content-length":
                            length = int(value)
                        elif name.lower() == b"x-feelium-capture-t":
                            stamp = float(value)
                    await resp.content.readexactly(length + 2)
                    frames.append((time.perf_counter(), stamp))
                    if pause_s:
                        await asyncio.sleep(pause_s)
    return frames


def _reader_stats(frames: list[tuple[float, float]]) -> dict[str, float]:
    """Frames per second over the reading, the median/p95 gap between frames and the frames' age on arrival."""
    dropped = bool(frames) and bool(np.isnan(frames[-1][0]))
    frames = frames[:-1] if dropped else frames
    arrivals = [a for a, _ in frames]
    nan = {"median_ms": float("nan"), "p95_ms": float("nan")}
    gaps = summary(list(np.diff(arrivals))) if len(arrivals) > 2 else nan
    ages = summary([a - t for a, t in frames]) if frames else nan
    span = arrivals[-1] - arrivals[0] if len(arrivals) > 1 else float("nan")
    return {
        "fps": round((len(arrivals) - 1) / span, 2) if len(arrivals) > 1 else 0.0,
        "gap_median_ms": gaps["median_ms"],
        "gap_p95_ms": gaps["p95_ms"],
        "age_median_ms": ages["median_ms"],
        "age_p95_ms": ages["p95_ms"],
        "dropped_by_server": dropped,
    }


def _phase(readers: list[list[float]]) -> dict[str, Any]:
    stats = [_reader_stats(a) for a in readers]
    return {
        "readers": stats,
        "fps_median": round(float(np.median([s["fps"] for s in stats])), 2),
        "gap_p95_ms_worst": max(s["gap_p95_ms"] for s in stats),
    }


SLOW_READER_PAUSE_S = 0.1  # a headset that decodes at most ~10 frames/s
READER_RCVBUF_BYTES = 16 * 1024


def synthetic_frame(k: int, base: np.ndarray) -> np.ndarray:
    """Frame ``k`` of a moving, camera-like (smooth, ~25 kB as JPEG) 640x480 test video."""
    return np.roll(base, k * 4, axis=1)


async def bench_mjpeg(server: ServerThread, seconds: float, fps: float) -> dict[str, Any]:
    """Three readers alone (baseline), then the same three plus a fourth client that never reads."""
    hub = server.hub
    assert hub is not None and server.app is not None
    link = link_of(server.app)
    rng = np.random.default_rng(0)
    base = cv2.GaussianBlur(rng.integers(0, 255, (480, 640, 3), dtype=np.uint8), (0, 0), 3)
    stop = asyncio.Event()

    async def publisher() -> int:
        k = 0
        t0 = time.perf_counter()
        while not stop.is_set():
            k += 1
            server.call(hub.front_video.publish, time.perf_counter(), synthetic_frame(k, base))
            await asyncio.sleep(max(0.0, t0 + k / fps - time.perf_counter()))
        return k

    pub = asyncio.create_task(publisher())
    await asyncio.sleep(0.3)
    baseline = _phase(list(await asyncio.gather(*(_mjpeg_reader(server.api, seconds, f"reader-{i}") for i in range(3)))))

    dropped_before = link.counters.get("stalled_clients_dropped", 0)
    stalled = socket.socket()
    stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    stalled.setblocking(False)
    await asyncio.get_running_loop().sock_connect(stalled, ("127.0.0.1", server.port))
    stalled.send(f"GET /api/v1/video/front.mjpeg?token={TOKEN}&client=stalled HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
    t_stall = time.perf_counter()
    drop_seen: list[float] = []

    async def watch_drop() -> None:
        while time.perf_counter() - t_stall < seconds + 5.0:
            if link.counters.get("stalled_clients_dropped", 0) > dropped_before:
                drop_seen.append(time.perf_counter() - t_stall)
                return
            await asyncio.sleep(0.01)

    watcher = asyncio.create_task(watch_drop())
    with_stalled = _phase(list(await asyncio.gather(*(_mjpeg_reader(server.api, seconds, f"reader-{i}") for i in range(3)))))
    await watcher
    limit = link.config.stream_inflight_bytes
    slow: dict[str, Any] = {}
    for name, inflight in (("no_inflight_limit", 0), ("inflight_limit", limit)):
        server.call(setattr, link, "config", replace(link.config, stream_inflight_bytes=inflight))
        await asyncio.sleep(0.05)
        slow[name] = {"inflight_bytes": inflight, **_reader_stats(await _mjpeg_reader(server.api, seconds, "slow-reader", SLOW_READER_PAUSE_S))}
    stop.set()
    published = await pub
    stalled.close()
    return {
        "published_fps": fps,
        "frames_published": published,
        "jpeg_encodes": link.videos["front"].encoded,
        "write_timeout_s": server.config.stream_write_timeout_s,
        "baseline_3_readers": baseline,
        "3_readers_plus_1_stalled": with_stalled,
        "ratio_fps_with_stalled_vs_baseline": round(with_stalled["fps_median"] / max(baseline["fps_median"], 1e-9), 3),
        "slow_reader": {"pause_per_frame_ms": 1000 * SLOW_READER_PAUSE_S, **slow},
        "slow_reader_age_ratio": round(
            slow["inflight_limit"]["age_median_ms"] / max(slow["no_inflight_limit"]["age_median_ms"], 1e-9), 3
        ),
        "stalled_dropped": bool(drop_seen),
        "stalled_dropped_after_s": round(drop_seen[0], 3) if drop_seen else None,
    }


SPEECH_RATE = 16000
SPEECH_CHUNK_S = 0.040  # the audio service's default chunk ([audio] chunk_ms)


def _speech_stats(delays: list[float], arrivals: list[float]) -> dict[str, Any]:
    """Capture -> receipt delay and inter-arrival gaps (what a jitter buffer must absorb), in ms."""
    d = np.asarray(delays) * 1000.0
    gaps = np.diff(np.asarray(arrivals)) * 1000.0
    pct = lambda a, q: round(float(np.percentile(a, q)), 3) if a.size else float("nan")  # noqa: E731
    return {
        "chunks": int(d.size),
        "delay_median_ms": pct(d, 50), "delay_p95_ms": pct(d, 95), "delay_p99_ms": pct(d, 99),
        "gap_p50_ms": pct(gaps, 50), "gap_p99_ms": pct(gaps, 99),
        "gap_dev_p99_ms": pct(np.abs(gaps - 1000.0 * SPEECH_CHUNK_S), 99),
    }  # fmt: skip


async def bench_speech(server: ServerThread, seconds: float) -> dict[str, Any]:
    """40 ms chunks published on the server's bus at the capture rate, read at once by a long-poll client
    (``GET /speech``, the old way) and a stream client (``GET /speech/stream``); an in-process bus subscriber
    is the baseline. Capture times are stamped on the hub clock (``perf_counter`` here, the one clock), so
    delay = receipt - capture_t needs no offset; a long-polled WAV of k chunks dates its chunks back from
    ``X-Feelium-Capture-T`` (its last sample) in steps of 40 ms."""
    hub = server.hub
    assert hub is not None
    samples = int(SPEECH_RATE * SPEECH_CHUNK_S)
    pcm = (np.sin(np.arange(samples) * 2 * np.pi * 440 / SPEECH_RATE) * 3000).astype("<i2").tobytes()
    n = max(10, int(seconds / SPEECH_CHUNK_S))
    got: dict[str, tuple[list[float], list[float]]] = {k: ([], []) for k in ("bus", "long_poll", "stream")}
    done = threading.Event()

    async def bus_listener() -> None:
        sub = hub.bus.subscribe([SpeechOut], maxsize=n + 8)
        while len(got["bus"][0]) < n:
            chunk = await sub.get()
            now = time.perf_counter()
            got["bus"][0].append(now - chunk.t)
            got["bus"][1].append(now)
        sub.close()
        done.set()

    asyncio.run_coroutine_threadsafe(bus_listener(), server.loop)
    requests = 0
    stop = asyncio.Event()
    async with aiohttp.ClientSession(headers=AUTH | {"X-Feelium-Client": "speech-bench"}) as session:
        async def long_poll() -> None:
            nonlocal requests
            after = 0
            async with session.get(server.api + "/speech", params={"timeout": 0}) as resp:
                after = int(resp.headers["X-Speech-Seq"])
            while not stop.is_set():
                async with session.get(server.api + "/speech", params={"after": after, "timeout": 1}) as resp:
                    body = await resp.read()
                    now = time.perf_counter()
                    requests += 1
                    after = int(resp.headers["X-Speech-Seq"])
                    if resp.status != 200:
                        continue
                    last_t = float(resp.headers["X-Feelium-Capture-T"])
                k = round((len(body) - 44) / 2 / samples)  # PCM16 WAV: a 44-byte header, then the chunks' samples
                for j in range(k):
                    got["long_poll"][0].append(now - (last_t - (k - 1 - j) * SPEECH_CHUNK_S))
                    got["long_poll"][1].append(now)

        async def stream() -> None:
            async with session.ws_connect(server.api.replace("http", "ws", 1) + "/speech/stream") as ws:
                await ws.receive_json()
                while not stop.is_set():
                    try:
                        msg = await ws.receive(timeout=0.5)
                    except asyncio.TimeoutError:
                        continue
                    if msg.type != aiohttp.WSMsgType.BINARY:
                        return
                    now = time.perf_counter()
                    frame = decode_frame(msg.data)
                    got["stream"][0].append(now - frame.capture_t)
                    got["stream"][1].append(now)

        readers = [asyncio.create_task(long_poll()), asyncio.create_task(stream())]
        await asyncio.sleep(0.3)
        t0 = time.perf_counter()
        for k in range(n):  # an absolute schedule, as a sound card delivers chunks
            await asyncio.sleep(max(0.0, t0 + (k + 1) * SPEECH_CHUNK_S - time.perf_counter()))
            server.call(hub.bus.publish, SpeechOut(pcm, SPEECH_RATE, time.perf_counter()))
        await asyncio.sleep(0.5)
        stop.set()
        await asyncio.wait_for(asyncio.gather(*readers), 10)
        span = time.perf_counter() - t0
    await asyncio.to_thread(done.wait, 10)
    out: dict[str, Any] = {"chunk_ms": 1000 * SPEECH_CHUNK_S, "chunks_published": n}
    for kind, (delays, arrivals) in got.items():
        out[kind] = _speech_stats(delays, arrivals)
    out["long_poll"]["requests_per_s"] = round(requests / span, 1)
    out["stream"]["requests_per_s"] = 0.0  # one connection for the whole run
    lp, st = out["long_poll"], out["stream"]
    out["ratio_delay_median_stream_vs_long_poll"] = round(st["delay_median_ms"] / max(lp["delay_median_ms"], 1e-9), 3)
    out["ratio_gap_dev_p99_stream_vs_long_poll"] = round(st["gap_dev_p99_ms"] / max(lp["gap_dev_p99_ms"], 1e-9), 3)
    return out


async def run_bench(n: int, seconds: float, fps: float, speech_seconds: float = 10.0, abuse: bool = True) -> dict[str, Any]:
    config = replace(HttpConfig(), motion_rate_per_s=1000.0, motion_burst=1000, stream_write_timeout_s=1.0,
                     event_ring_size=4096, keepalive_s=5.0)  # fmt: skip
    with ServerThread(config) as server:
        result = {
            "motion_round_trip": await bench_motion(server, n),
            "touch_event_latency": await bench_events(server, n),
            "mjpeg_4_clients_1_stalled": await bench_mjpeg(server, seconds, fps),
            "speech_stream_vs_long_poll": await bench_speech(server, speech_seconds),
        }
    result["stop_under_flood"] = await bench_stop_under_flood(max(10, n // 3))
    if abuse:
        result["rss_under_abuse"] = await run_abuse()
    return result


def format_table(result: dict[str, Any]) -> str:
    lines = ["| measurement | median ms | p95 ms | ratio to baseline |", "|---|---|---|---|"]
    m = result["motion_round_trip"]
    lines.append(f"| GET /health round trip (baseline) | {m['baseline_health']['median_ms']} | {m['baseline_health']['p95_ms']} | 1.0 |")
    lines.append(f"| POST /motion sent -> command on the hub | {m['sent_to_hub']['median_ms']} | {m['sent_to_hub']['p95_ms']} | |")
    lines.append(f"| POST /motion round trip | {m['motion']['median_ms']} | {m['motion']['p95_ms']} | {m['ratio_median']} |")
    f = result["stop_under_flood"]
    for label, key in (("`stop`, quiet (baseline)", "quiet"), ("`stop` from a bystander, during a flood", "bystander_during_flood"),
                       ("`stop` from the flooder itself", "flooder_own_stop")):  # fmt: skip
        r = f[key]
        ratio = "1.0" if key == "quiet" else round(r["median_ms"] / f["quiet"]["median_ms"], 2)
        lines.append(f"| {label}: sent -> on the hub ({r['n']} accepted, {r['refused']} refused) "
                     f"| {r['median_ms']} | {r['p95_ms']} | {ratio} |")  # fmt: skip
    e = result["touch_event_latency"]
    lines.append(f"| bus publish -> in-process subscriber (baseline) | {e['baseline_bus']['median_ms']} | {e['baseline_bus']['p95_ms']} | 1.0 |")
    for kind in ("long_poll", "sse", "websocket"):
        lines.append(f"| bus publish -> {kind} client | {e[kind]['median_ms']} | {e[kind]['p95_ms']} | {e[kind]['ratio_median_vs_bus']} |")
    v = result["mjpeg_4_clients_1_stalled"]
    b, w = v["baseline_3_readers"], v["3_readers_plus_1_stalled"]
    lines += [
        "",
        f"MJPEG 640x480 published at {v['published_fps']} fps, write timeout {v['write_timeout_s']} s",
        "",
        "| MJPEG readers | fps per reader | frame gap median ms | frame gap p95 ms |",
        "|---|---|---|---|",
        f"| 3 readers (baseline) | {', '.join(str(r['fps']) for r in b['readers'])} "
        f"| {', '.join(str(r['gap_median_ms']) for r in b['readers'])} | {', '.join(str(r['gap_p95_ms']) for r in b['readers'])} |",
        f"| 3 readers + 1 stalled | {', '.join(str(r['fps']) for r in w['readers'])} "
        f"| {', '.join(str(r['gap_median_ms']) for r in w['readers'])} | {', '.join(str(r['gap_p95_ms']) for r in w['readers'])} |",
        "",
        f"| slow reader ({READER_RCVBUF_BYTES // 1024} kB buffers, pauses 100 ms per frame) | fps "
        "| frame age on arrival median ms | p95 ms |",
        "|---|---|---|---|",
        *(
            f"| {label}{' (dropped by the server)' if r['dropped_by_server'] else ''} | {r['fps']} "
            f"| {r['age_median_ms']} | {r['age_p95_ms']} |"
            for label, r in (
                ("no in-flight limit (baseline)", v["slow_reader"]["no_inflight_limit"]),
                (f"in-flight limit {v['slow_reader']['inflight_limit']['inflight_bytes']} B", v["slow_reader"]["inflight_limit"]),
            )
        ),
        "",
        f"median fps ratio (with stalled / baseline): {v['ratio_fps_with_stalled_vs_baseline']}; "
        f"stalled client dropped: {v['stalled_dropped']} after {v['stalled_dropped_after_s']} s; "
        f"JPEG encodes / frames published: {v['jpeg_encodes']} / {v['frames_published']}",
    ]
    lines += ["", f"flood: {f['flood_requests_per_s']} motion requests/s from one client ({FLOOD_TASKS} in flight), "
              f"answered {f['flood_statuses']} (status: count); shipped rate limits"]
    sp = result["speech_stream_vs_long_poll"]
    lines += [
        "",
        f"Speech: {sp['chunks_published']} chunks of {sp['chunk_ms']:g} ms, capture (hub clock) -> client receipt",
        "",
        "| speech transport | chunks | delay median ms | p95 | p99 | gap p50 ms | gap p99 ms | abs(gap - 40) p99 ms | requests/s |",
        "|---|---|---|---|---|---|---|---|---|",
        *(
            f"| {label} | {r['chunks']} | {r['delay_median_ms']} | {r['delay_p95_ms']} | {r['delay_p99_ms']} "
            f"| {r['gap_p50_ms']} | {r['gap_p99_ms']} | {r['gap_dev_p99_ms']} | {r.get('requests_per_s', '')} |"
            for label, r in (("in-process bus (baseline)", sp["bus"]), ("GET /speech long-poll", sp["long_poll"]),
                             ("GET /speech/stream WebSocket", sp["stream"]))
        ),
        "",
        f"stream / long-poll: delay median {sp['ratio_delay_median_stream_vs_long_poll']}, "
        f"abs(gap - 40 ms) p99 {sp['ratio_gap_dev_p99_stream_vs_long_poll']}",
    ]
    if "rss_under_abuse" in result:
        lines += format_abuse(result["rss_under_abuse"])
    return "\n".join(lines)


def bench_http_command(args: Any) -> int:
    if args.requests < 10 or args.seconds <= 0 or args.fps <= 0:
        print("feelium bench link: --requests >= 10, --seconds > 0 and --fps > 0 please", file=sys.stderr)
        return 2
    speech_seconds = getattr(args, "speech_seconds", 10.0)
    if speech_seconds <= 0:
        print("feelium bench link: --speech-seconds > 0 please", file=sys.stderr)
        return 2
    result = asyncio.run(run_bench(args.requests, args.seconds, args.fps, speech_seconds, not getattr(args, "no_abuse", False)))
    emit_report(format_table(result), result, args.json)
    return 0
