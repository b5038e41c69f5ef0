"""A headset-link app over a hub the tests feed directly, with a controllable clock."""

from __future__ import annotations

from dataclasses import replace

import pytest

from feelium.http.app import create_app, link_of
from feelium.http.config import HttpConfig
from feelium.hub import Hub

from tests.http.http_support import TOKEN, FakeClock


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()


@pytest.fixture
def hub(clock: FakeClock) -> Hub:
    return Hub(clock=clock)


@pytest.fixture
def http_config() -> HttpConfig:
    return replace(HttpConfig(), token=TOKEN, stream_write_timeout_s=0.3, keepalive_s=0.5, event_ring_size=8)


@pytest.fixture
async def client(aiohttp_client, hub: Hub, http_config: HttpConfig):  # type: ignore[no-untyped-def]
    app = create_app(http_config, hub, TOKEN)
    c = await aiohttp_client(app)
    c.link = link_of(app)
    return c


@pytest.fixture(scope="package")
def live(tmp_path_factory):  # type: ignore[no-untyped-def]
    """One real sim-mode daemon for every end-to-end test of the headset link (stopped when tests/http ends:
    left running, it would take half a core from the rest of the suite)."""
    from feelium.lab.daemon.live import start_daemon, stop_daemon

    daemon = start_daemon(tmp_path_factory.mktemp("live"))
    yield daemon
    stop_daemon(daemon)
