"""``feelium bench link``'s abuse phase: what hostile clients cost a real daemon's memory, and whether `stop` still wins.

The unit and live tests prove each limit refuses what it must; this phase
measures what the refusals cost the whole daemon (its projector decodes the
faces, its stream slots hold sockets), as the issue asks: the daemon's RSS
may grow by less than 50 MB under any abuse. A real ``feelium run --sim``
runs in its own process with the shipped HTTP limits; for each phase its
peak RSS is reset (Linux ``/proc/PID/clear_refs``), the abuse runs, and the
phase reports the peak growth, what stays resident afterwards, how every
request was answered (a 5xx would be a failure) and whether a `stop` sent
right after is accepted. The baseline, measured in the same run, is the same
daemon left alone for as long as a phase lasts: its own swing in memory.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import statistics
import socket
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any, Awaitable, Callable

import aiohttp
import cv2
import numpy as np

from feelium.http.config import HttpConfig
from feelium.lab.daemon.live import LiveDaemon, start_daemon, stop_daemon

RSS_GROWTH_GOAL_MB = 50.0
IDLE_S = 3.0
FLOOD_CLIENTS = 4
FLOOD_IN_FLIGHT = 8
STALLED_STREAMS = 24  # more than the shipped 16 slots, from 6 clients of 4 streams each
SILENT_SUBSCRIBERS = 50
CONCURRENT_UPLOADS = 24
CONCURRENT_ROUNDS = 4
HOSTILE_REPEATS = 20
STOPS_DURING_FLOOD = 40
SOCKET_BUFFER_BYTES = 4096


def declare_size(jpeg: bytes, width: int, height: int) -> bytes:
    """The same JPEG with its frame header claiming another size (what a hostile upload does)."""
    i = jpeg.index(b"\xff\xc0") if b"\xff\xc0" in jpeg else jpeg.index(b"\xff\xc2")
    return jpeg[: i + 5] + height.to_bytes(2, "big") + width.to_bytes(2, "big") + jpeg[i + 9 :]


def progressive_jpeg(side: int, seed: int = 5) -> bytes:
    """A square progressive 4:4:4 JPEG of smooth noise: the costliest kind to decode for its size."""
    coarse = np.random.default_rng(seed).integers(0, 255, (max(1, side // 16), max(1, side // 16), 3), np.uint8)
    image = cv2.resize(coarse, (side, side), interpolation=cv2.INTER_CUBIC)
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90, cv2.IMWRITE_JPEG_PROGRESSIVE, 1,
                                            cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444])  # fmt: skip
    if not ok:
        raise RuntimeError("OpenCV could not encode the test face")
    return buf.tobytes()


def rss_kb(pid: int) -> dict[str, int]:
    """A process's resident memory now (VmRSS) and at its peak since the last reset (VmHWM), in kB."""
    fields = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        name, _, value = line.partition(":")
        if name in ("VmRSS", "VmHWM"):
            fields[name] = int(value.split()[0])
    return fields


def reset_peak_rss(pid: int) -> None:
    Path(f"/proc/{pid}/clear_refs").write_text("5")  # VmHWM := VmRSS


class Abuser:
    """The hostile clients, each phase a coroutine that returns how its requests were answered."""

    def __init__(self, daemon: LiveDaemon, session: aiohttp.ClientSession, write_timeout_s: float) -> None:
        self.daemon = daemon
        self.session = session
        self.write_timeout_s = write_timeout_s  # the daemon's: silent clients are held for longer than this
        self.statuses: Counter[int] = Counter()
        self.notes: dict[str, Any] = {}  # a phase's own findings, beyond the statuses

    async def request(self, method: str, path: str, client: str | None, **kw: Any) -> int:
        """One request as ``client`` (``None``: without a client id, as the tests' clients and a plain browser)."""
        headers = self.daemon.auth | ({"X-Feelium-Client": client} if client else {}) | kw.pop("headers", {})
        async with self.session.request(method, self.daemon.api + path, headers=headers, **kw) as resp:
            await resp.read()
            self.statuses[resp.status] += 1
            return resp.status

    async def idle(self) -> None:
        await asyncio.sleep(IDLE_S)

    async def face_uploads(self) -> None:
        """An 8000x8000 face (refused from its header), then three of the largest faces the daemon admits, each
        waited for until the projector has decoded it."""
        config = HttpConfig()
        largest = progressive_jpeg(math.isqrt(config.max_face_pixels))
        huge = declare_size(progressive_jpeg(64), 8000, 8000)
        jpeg = {"Content-Type": "image/jpeg"}
        await self.request("PUT", "/face", "uploader", data=huge, headers=jpeg)
        for _ in range(3):
            faces = self.daemon.health()["services"]["projector"]["faces"]
            await self.request("PUT", "/face", "uploader", data=largest, headers=jpeg)
            for _ in range(100):
                if self.daemon.health()["services"]["projector"]["faces"] > faces:
                    break
                await asyncio.sleep(0.05)

    async def concurrent_uploads(self) -> None:
        """Four rounds of 24 of the largest admitted faces sent at once, each from a client id of its own (ids are
        free to pick), so no per-client limit holds them back: only the daemon-wide upload gate does."""
        largest = progressive_jpeg(math.isqrt(HttpConfig().max_face_pixels), seed=6)
        jpeg = {"Content-Type": "image/jpeg"}
        for round_ in range(CONCURRENT_ROUNDS):
            await asyncio.gather(*(self.request("PUT", "/face", f"uploader-{round_}-{i}", data=largest, headers=jpeg)
                                   for i in range(CONCURRENT_UPLOADS)))  # fmt: skip

    async def motion_flood(self) -> None:
        """Several clients, each keeping motion requests in flight far past its rate limit."""
        until = time.perf_counter() + IDLE_S

        async def flooder(client: str) -> None:
            while time.perf_counter() < until:
                await self.request("POST", "/motion", client, json={"command": "forward", "hold_ms": 500})

        await asyncio.gather(*(flooder(f"flood-{c}") for c in range(FLOOD_CLIENTS) for _ in range(FLOOD_IN_FLIGHT)))

    async def socket_flood(self) -> None:
        """One client floods its events WebSocket with motion commands as fast as it can write, while a bystander
        sends a `stop` every 50 ms over HTTP: the flooder must be cut off and every stop land promptly."""
        ws = await self.session.ws_connect(self.daemon.api + "/events/ws", headers=self.daemon.auth | {
            "X-Feelium-Client": "socket-flooder"})  # fmt: skip
        self.statuses[101] += 1
        message = json.dumps({"type": "motion", "id": 1, "command": "forward", "take_over": True})

        async def flood() -> int:
            sent = 0
            with contextlib.suppress(ConnectionError, RuntimeError, aiohttp.ClientError):
                while not ws.closed:
                    await ws.send_str(message)
                    sent += 1
            return sent

        async def drain() -> None:
            with contextlib.suppress(ConnectionError, aiohttp.ClientError, asyncio.TimeoutError):
                while not ws.closed and (await ws.receive(timeout=IDLE_S)).type not in (
                        aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.ERROR):  # fmt: skip
                    pass

        flooding = asyncio.gather(flood(), drain())
        stops = []
        for _ in range(STOPS_DURING_FLOOD):
            t0 = time.perf_counter()
            await self.request("POST", "/motion", "bystander", json={"command": "stop"})
            stops.append(1000.0 * (time.perf_counter() - t0))
            await asyncio.sleep(0.05)
        sent, _ = await asyncio.wait_for(flooding, IDLE_S + 5.0)
        if not ws.closed:
            await ws.close()
        self.notes.update({
            "flood_messages_sent": sent, "flooder_close_code": None if ws.close_code is None else int(ws.close_code),
            "bystander_stop_ms_median": round(statistics.median(stops), 1), "bystander_stop_ms_max": round(max(stops), 1),
        })  # fmt: skip

    async def hostile_bodies(self) -> None:
        """Bodies that once gave 500s or cost memory: deep nesting, huge numbers, bad UTF-8, a wrong content type,
        an oversized body."""
        deep = "[" * 5000 + "]" * 5000
        bodies: list[tuple[str, bytes, str]] = [
            ("/motion", deep.encode(), "application/json"),
            ("/motion", b'{"command": "forward", "hold_ms": 1' + b"0" * 400 + b"}", "application/json"),
            ("/sim/press", b'{"x": 1e400, "y": 10}', "application/json"),
            ("/motion", b'{"command": "\xff\xfe"}', "application/json"),
            ("/motion", b'{"command": "forward"}', "text/plain"),
            ("/motion", b"[" + b"0," * 2_000_000 + b"0]", "application/json"),
        ]
        for _ in range(HOSTILE_REPEATS):
            for path, body, kind in bodies:
                await self.request("POST", path, "hostile", data=body, headers={"Content-Type": kind})

    async def stalled_streams(self) -> None:
        """More MJPEG streams than there are slots, from clients that ask and never read (small buffers, as a
        phone's), held for longer than the write timeout; then a fresh reader must get a frame."""
        writers = []
        host, port = "127.0.0.1", self.daemon.port
        for i in range(STALLED_STREAMS):
            sock = socket.socket()
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, SOCKET_BUFFER_BYTES)
            sock.connect((host, port))
            sock.setblocking(False)
            reader, writer = await asyncio.open_connection(sock=sock)
            writer.write(
                f"GET /api/v1/video/front.mjpeg HTTP/1.1\r\nHost: {host}:{port}\r\n"
                f"Authorization: Bearer {self.daemon.token}\r\nX-Feelium-Client: stalled-{i // 4}\r\n\r\n".encode()
            )
            status_line = await asyncio.wait_for(reader.readline(), 5.0)  # read the answer's first line, then stall
            self.statuses[int(status_line.split()[1])] += 1
            writers.append(writer)
        await asyncio.sleep(self.write_timeout_s + IDLE_S)
        try:
            async with self.session.get(self.daemon.api + "/video/front.mjpeg", headers=self.daemon.auth | {
                    "X-Feelium-Client": "fresh"}, timeout=aiohttp.ClientTimeout(total=5)) as resp:  # fmt: skip
                self.statuses[resp.status] += 1
                self.notes["fresh_reader_status"] = resp.status
                if resp.status == 200:
                    await resp.content.readuntil(b"\r\n\r\n")
        finally:
            for writer in writers:
                writer.close()

    async def silent_subscribers(self) -> None:
        """Event WebSockets from one address (as many client ids) that never read, for longer than the write
        timeout: the address's event-stream slots take the first ones, the rest get 429."""
        sockets = []
        for i in range(SILENT_SUBSCRIBERS):
            try:
                ws = await self.session.ws_connect(self.daemon.api + "/events/ws", headers=self.daemon.auth | {
                    "X-Feelium-Client": f"silent-{i}"})  # fmt: skip
            except aiohttp.WSServerHandshakeError as exc:  # over the event-stream slots: 429
                self.statuses[exc.status] += 1
                continue
            self.statuses[101] += 1  # switched protocols: the upgrade was accepted
            sockets.append(ws)
        await asyncio.sleep(self.write_timeout_s + IDLE_S)
        for ws in sockets:
            await ws.close()


async def stop_accepted(abuser: Abuser) -> bool:
    """A `stop` from a client of its own (id-less, so it also hands the lease back to id-less clients)."""
    return await abuser.request("POST", "/motion", None, json={"command": "stop"}) == 200


async def measure_phase(abuser: Abuser, phase: Callable[[], Awaitable[None]]) -> dict[str, Any]:
    """Run one phase between two readings of the daemon's memory, then send a `stop` and read what stays."""
    pid = abuser.daemon.process.pid
    abuser.statuses.clear()
    abuser.notes = {}
    reset_peak_rss(pid)
    before = rss_kb(pid)["VmRSS"]
    t0 = time.perf_counter()
    await phase()
    seconds = time.perf_counter() - t0
    statuses = dict(abuser.statuses)
    peak = rss_kb(pid)["VmHWM"]
    stop_ok = await stop_accepted(abuser)
    await asyncio.sleep(1.0)  # what stays once the phase's clients are gone
    after = rss_kb(pid)["VmRSS"]
    return {
        "seconds": round(seconds, 2),
        "rss_before_mb": round(before / 1024, 1),
        "rss_peak_growth_mb": round((peak - before) / 1024, 1),
        "rss_retained_mb": round((after - before) / 1024, 1),
        "statuses": {str(k): v for k, v in sorted(statuses.items())},
        "server_errors": sum(v for k, v in statuses.items() if k >= 500),
        "stop_accepted_after": stop_ok,
    } | abuser.notes


async def run_abuse() -> dict[str, Any]:
    """Every phase against one daemon, in order, with the idle baseline first; the daemon must outlive them all."""
    with tempfile.TemporaryDirectory(prefix="feelium-abuse-") as tmp:
        daemon = start_daemon(Path(tmp), http_toml="")
        try:
            connector = aiohttp.TCPConnector(limit=0)
            async with aiohttp.ClientSession(connector=connector) as session:
                abuser = Abuser(daemon, session, HttpConfig().stream_write_timeout_s)
                phases = {name: await measure_phase(abuser, getattr(abuser, name)) for name in (
                    "idle", "face_uploads", "concurrent_uploads", "motion_flood", "socket_flood", "hostile_bodies", "stalled_streams", "silent_subscribers")}  # fmt: skip
            alive = daemon.process.poll() is None and "services" in daemon.health()
        finally:
            stop_daemon(daemon)
    worst = max(p["rss_peak_growth_mb"] for name, p in phases.items() if name != "idle")
    return {
        "phases": phases,
        "worst_peak_growth_mb": worst,
        "goal_growth_mb": RSS_GROWTH_GOAL_MB,
        "goal_met": worst < RSS_GROWTH_GOAL_MB and all(p["server_errors"] == 0 and p["stop_accepted_after"]
                                                       for p in phases.values()) and alive,  # fmt: skip
        "daemon_alive_after": alive,
    }


def format_abuse(result: dict[str, Any]) -> list[str]:
    lines = [
        "",
        f"Abuse against a real sim daemon (shipped HTTP limits): peak RSS growth per phase, goal < {result['goal_growth_mb']:g} MB",
        "",
        "| phase | s | RSS before MB | peak growth MB | retained MB | answers (status: count) | 5xx | `stop` after |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, p in result["phases"].items():
        label = f"{name} (baseline)" if name == "idle" else name
        lines.append(f"| {label} | {p['seconds']} | {p['rss_before_mb']} | {p['rss_peak_growth_mb']} | {p['rss_retained_mb']} "
                     f"| {p['statuses'] or '-'} | {p['server_errors']} | {'accepted' if p['stop_accepted_after'] else 'REFUSED'} |")  # fmt: skip
    flood = result["phases"].get("socket_flood")
    if flood:
        lines.append(f"\nsocket flood: the flooder sent {flood['flood_messages_sent']} messages before it was cut off "
                     f"(close {int(flood['flooder_close_code'] or 0)}); a bystander's `stop` round trip meanwhile "
                     f"{flood['bystander_stop_ms_median']} ms median, {flood['bystander_stop_ms_max']} ms max")  # fmt: skip
    lines.append(f"\nworst peak growth {result['worst_peak_growth_mb']} MB; daemon alive after: {result['daemon_alive_after']}; "
                 f"goal met: {result['goal_met']}")  # fmt: skip
    return lines
