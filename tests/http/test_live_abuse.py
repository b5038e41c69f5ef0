"""Issue 14 against a real sim daemon: a flood then stop from two clients, and the memory a big face upload costs."""

from __future__ import annotations

import asyncio
import math
from pathlib import Path

import aiohttp
import cv2
import numpy as np
import pytest

from feelium.http.config import HttpConfig
from tests.http.test_limit_cores import declare_size

pytestmark = pytest.mark.slow


async def test_a_flood_then_stop_from_the_flooder_and_from_another_client(live):
    a, b = live.auth | {"X-Feelium-Client": "flooder"}, live.auth | {"X-Feelium-Client": "bystander"}
    async with aiohttp.ClientSession() as session:

        async def post(headers: dict[str, str], command: str) -> int:
            async with session.post(f"{live.api}/motion", json={"command": command}, headers=headers) as resp:
                await resp.read()
                return resp.status

        statuses = await asyncio.gather(*(post(a, "forward") for _ in range(100)), post(b, "stop"), post(a, "stop"))
        assert statuses[-2:] == [200, 200]
        assert 429 in statuses[:100]
        assert await post(a, "stop") == 200 and await post(b, "stop") == 200
        async with session.get(f"{live.api}/motion", headers=b) as resp:
            assert (await resp.json())["active"] is False
        assert await post(a, "forward") in (409, 429)  # the bystander's stop holds the lease
        assert await post(live.auth, "stop") == 200  # leave the lease with the id-less client the other tests are


def _rss_kb(pid: int) -> dict[str, int]:
    fields = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        name, _, value = line.partition(":")
        if name in ("VmRSS", "VmHWM"):
            fields[name] = int(value.split()[0])
    return fields


def _progressive_jpeg(side: int) -> bytes:
    coarse = np.random.default_rng(5).integers(0, 255, (side // 16, side // 16, 3), np.uint8)
    image = cv2.resize(coarse, (side, side), interpolation=cv2.INTER_CUBIC)
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90, cv2.IMWRITE_JPEG_PROGRESSIVE, 1,
                                            cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444])  # fmt: skip
    assert ok
    return buf.tobytes()


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="peak RSS reset is Linux's")
async def test_face_uploads_grow_the_daemons_rss_by_less_than_50_mb(live):
    """The daemon's peak RSS (reset first) while it refuses an 8000x8000 face and shows the largest it admits."""
    pid = live.process.pid
    side = math.isqrt(HttpConfig().max_face_pixels)
    largest = _progressive_jpeg(side)
    assert len(largest) <= HttpConfig().max_face_bytes
    huge = declare_size(_progressive_jpeg(64), 8000, 8000)
    Path(f"/proc/{pid}/clear_refs").write_text("5")  # VmHWM := VmRSS
    before = _rss_kb(pid)["VmRSS"]
    headers = live.auth | {"Content-Type": "image/jpeg"}
    async with aiohttp.ClientSession() as session:
        async with session.put(f"{live.api}/face", data=huge, headers=headers) as resp:
            assert resp.status == 413 and (await resp.json())["error"] == "image_too_large"
        faces = live.health()["services"]["projector"]["faces"]
        for _ in range(3):
            async with session.put(f"{live.api}/face", data=largest, headers=headers) as resp:
                assert resp.status == 200
            for _ in range(100):  # the projector decodes it on its next tick
                if live.health()["services"]["projector"]["faces"] > faces:
                    break
                await asyncio.sleep(0.05)
            faces = live.health()["services"]["projector"]["faces"]
    growth_mb = (_rss_kb(pid)["VmHWM"] - before) / 1024.0
    print(f"daemon peak RSS growth over 3 uploads of a {side}x{side} progressive face: {growth_mb:.1f} MB")
    assert faces >= 3
    assert growth_mb < 50.0
