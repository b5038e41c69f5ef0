"""The daemon's event loop: uvloop where it imports, asyncio's on request or as ``auto``'s fallback, and the daemon
works on either (feelium/daemon/eventloop.py)."""

from __future__ import annotations

import asyncio
import logging
import sys

import pytest

from feelium.daemon.eventloop import loop_kind, new_event_loop
from feelium.events import TouchEvent
from feelium.hub import Hub
from feelium.settings import ConfigError

from .synthetic import PRESS_XY, write_press_recording
from .test_daemon_inprocess import _replay_config, _run_until


def _kind_of(choice):
    loop, kind = new_event_loop(choice)
    try:
        return kind, loop_kind(loop)
    finally:
        loop.close()


def test_asyncio_is_asyncio_whatever_is_installed():
    assert _kind_of("asyncio") == ("asyncio", "asyncio")


def test_uvloop_and_auto_give_uvloop_where_it_imports():
    pytest.importorskip("uvloop")
    assert _kind_of("uvloop") == ("uvloop", "uvloop")
    assert _kind_of("auto") == ("uvloop", "uvloop")


def test_auto_without_uvloop_falls_back_to_asyncio_and_says_so(monkeypatch, caplog):
    monkeypatch.setitem(sys.modules, "uvloop", None)  # import uvloop now raises ImportError
    with caplog.at_level(logging.WARNING, logger="feelium.daemon.eventloop"):
        assert _kind_of("auto") == ("asyncio", "asyncio")
    assert "uvloop cannot be imported" in caplog.text


def test_uvloop_asked_for_and_missing_is_a_config_error_naming_the_key(monkeypatch):
    monkeypatch.setitem(sys.modules, "uvloop", None)
    with pytest.raises(ConfigError, match="daemon.event_loop"):
        new_event_loop("uvloop")


@pytest.mark.slow
def test_the_daemon_on_uvloop_reports_it_and_its_touches_reach_the_bus(tmp_path):
    pytest.importorskip("uvloop")
    recording = write_press_recording(tmp_path / "press")
    hub = Hub()
    sub = hub.bus.subscribe([TouchEvent])
    config = _replay_config(recording)
    with asyncio.Runner(loop_factory=lambda: new_event_loop("uvloop")[0]) as runner:
        runner.run(_run_until(config, lambda h, s: s.records["touch"].state == "finished", hub=hub))
    events = sub.drain()
    assert [e.phase for e in events][0] == "down" and events[-1].phase == "up"
    assert abs(events[0].x - PRESS_XY[0]) < 4 and abs(events[0].y - PRESS_XY[1]) < 4
    assert hub.health()["event_loop"] == "uvloop"
