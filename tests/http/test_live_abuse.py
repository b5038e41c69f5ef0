"""Issue 14 against a real sim daemon: a flood then stop from two clients, and the memory a big face upload costs."""

from __future__ import annotations

import asyncio
from pathlib import Path

import aiohttp
import pytest

from feelium.http.config import HttpConfig
from feelium.lab.http.abuse import RSS_GROWTH_GOAL_MB, Abuser, measure_phase

pytestmark = pytest.mark.slow


async def test_a_flood_then_stop_from_the_flooder_and_from_another_client(live):
    a, b = live.auth | {"X-Feelium-Client": "flooder"}, live.auth | {"X-Feelium-Client": "bystander"}
    # 32 connections at most: past max_connections_per_address (64) the daemon would close them, as it must
    async with aiohttp.ClientSession(connector=aiohttp.TCPConnector(limit=32)) as session:

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


async def _phase(live, name: str) -> dict:  # type: ignore[no-untyped-def]
    async with aiohttp.ClientSession(connector=aiohttp.TCPConnector(limit=0)) as session:
        abuser = Abuser(live, session, write_timeout_s=0.5)  # the live daemon's (tests' short timeouts)
        return await measure_phase(abuser, getattr(abuser, name))


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="peak RSS reset is Linux's")
async def test_face_uploads_grow_the_daemons_rss_by_less_than_50_mb(live):
    """The daemon's peak RSS (reset first) while it refuses an 8000x8000 face and shows the largest it admits
    three times; `feelium bench link` runs the same phase with the shipped limits."""
    faces = live.health()["services"]["projector"]["faces"]
    result = await _phase(live, "face_uploads")
    print(f"daemon peak RSS growth over 3 uploads of the largest admitted face: {result['rss_peak_growth_mb']} MB")
    assert result["statuses"] == {"200": 3, "413": 1}
    assert live.health()["services"]["projector"]["faces"] >= faces + 3  # each one was decoded and shown
    assert result["rss_peak_growth_mb"] < RSS_GROWTH_GOAL_MB
    assert result["server_errors"] == 0 and result["stop_accepted_after"]


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="peak RSS reset is Linux's")
async def test_concurrent_face_uploads_from_many_client_ids_stay_under_50_mb(live):
    """96 of the largest faces, 24 at a time from as many client ids: the daemon-wide upload gate refuses what it
    cannot read at once (429 before the body is read), so memory does not stack (58 MB before the gate)."""
    result = await _phase(live, "concurrent_uploads")
    print(f"daemon peak RSS growth over 4 x 24 concurrent uploads: {result['rss_peak_growth_mb']} MB, {result['statuses']}")
    assert set(result["statuses"]) == {"200", "429"} and result["statuses"]["200"] >= 4  # the gate turned some away
    assert result["rss_peak_growth_mb"] < RSS_GROWTH_GOAL_MB
    assert result["server_errors"] == 0 and result["stop_accepted_after"]


async def test_hostile_bodies_get_4xx_and_stop_still_wins(live):
    result = await _phase(live, "hostile_bodies")
    assert result["server_errors"] == 0 and result["stop_accepted_after"]
    assert set(result["statuses"]) == {"400", "413", "415"}


async def test_stream_slots_held_by_stalled_readers_come_back(live):
    """More never-reading MJPEG clients than slots, from 6 client ids on one address: the address's cap refuses
    the surplus with 429 whatever ids it sends, the rest are dropped after the write timeout, and a fresh reader
    from the same address then gets its stream."""
    result = await _phase(live, "stalled_streams")
    statuses = result["statuses"]
    per_address = HttpConfig().max_streams_per_address
    assert statuses == {"200": per_address + 1, "429": 24 - per_address}  # the +1 is the fresh reader
    assert result["fresh_reader_status"] == 200 and result["server_errors"] == 0
    assert result["stop_accepted_after"]
