"""The bus never stalls a producer; newest-wins slots; the dead man lapses."""

from __future__ import annotations

import asyncio
import math
import threading

import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.bus import EventBus
from feelium.events import PresenceEvent, TouchEvent
from feelium.hub import Latest, StateBoard
from feelium.motion import MAX_HOLD_S, DeadManCommands


def _touch(i: int) -> TouchEvent:
    return TouchEvent(i, "down", None, i * 0.1, 1.0, 2.0, 0.1, 0.2, 0.5, 10, 0.4)


async def test_slow_subscriber_drops_oldest_and_counts():
    bus = EventBus()
    slow = bus.subscribe(maxsize=3)
    fast = bus.subscribe(maxsize=100)
    for i in range(10):
        bus.publish(_touch(i))
    assert [e.id for e in slow.drain()] == [7, 8, 9]
    assert slow.dropped == 7
    assert len(fast.drain()) == 10 and fast.dropped == 0
    assert bus.health()["dropped"] == 7


def test_take_on_another_thread_loses_nothing_and_keeps_the_order():
    """Flight takes its events on the serial thread while the loop publishes: every item once, in order."""
    bus = EventBus()
    n = 20000
    sub = bus.subscribe(maxsize=n)
    taken: list[int] = []
    done = threading.Event()

    def consumer() -> None:
        while not done.is_set():
            taken.extend(e.id for e in sub.take())
        taken.extend(e.id for e in sub.take())

    thread = threading.Thread(target=consumer)
    thread.start()
    for i in range(n):
        bus.publish(_touch(i))
    done.set()
    thread.join()
    assert taken == list(range(n))
    assert sub.delivered == n and sub.dropped == 0 and sub.take() == []


async def test_typed_subscription_and_wakeup():
    bus = EventBus()
    presence_only = bus.subscribe([PresenceEvent])
    waiter = asyncio.create_task(presence_only.get(timeout=1.0))
    await asyncio.sleep(0)
    bus.publish(_touch(1))
    bus.publish(PresenceEvent("approach", 1.0, 3, 4, 1.0, 2.0, 5, 3.0))
    got = await waiter
    assert isinstance(got, PresenceEvent)
    assert await presence_only.get(timeout=0.01) is None
    presence_only.close()
    assert bus.health()["subscribers"] == 0


def test_a_listener_that_raises_is_counted_and_neither_the_producer_nor_the_others_stop(caplog):
    """A consumer's fault must not stop the part that publishes: the item still reaches every other consumer."""
    bus = EventBus()
    sub = bus.subscribe([PresenceEvent])
    seen: list[object] = []

    def broken(item: object) -> None:
        raise RuntimeError("a consumer's bug")

    bus.listen([PresenceEvent], broken)
    bus.listen([PresenceEvent], seen.append)
    presence = PresenceEvent("approach", 1.0, 3, 4, 1.0, 2.0, 5, 3.0)
    bus.publish(presence)
    bus.publish(presence)
    assert seen == [presence, presence] and sub.take() == [presence, presence]
    assert bus.health()["listener_errors"] == 2
    assert sum("bus listener raised" in r.getMessage() for r in caplog.records) == 1  # logged once


async def test_a_listener_files_each_item_inside_publish_and_stops_when_told():
    """A listener runs in the producer's call (no task step per item), only for its types, until stopped."""
    from feelium.events import SpeechOut
    from feelium.http.speech import SpeechFeed

    bus = EventBus()
    seen: list[object] = []
    stop = bus.listen([PresenceEvent], seen.append)
    presence = PresenceEvent("approach", 1.0, 3, 4, 1.0, 2.0, 5, 3.0)
    bus.publish(_touch(1))
    bus.publish(presence)
    assert seen == [presence] and bus.health()["listeners"] == 1
    stop()
    stop()  # twice is harmless
    bus.publish(presence)
    assert seen == [presence] and bus.health()["listeners"] == 0
    feed = SpeechFeed(bus, keep_ms=200)
    feed.start()
    waiter = asyncio.create_task(feed.wait_numbered_after(0, timeout=1.0))
    await asyncio.sleep(0)
    chunk = SpeechOut(b"\0\0" * 640, 16000, 1.0)
    bus.publish(chunk)
    assert feed.last_seq == 1  # numbered before any task ran
    assert await waiter == [(1, chunk)]
    feed.close()
    bus.publish(chunk)
    assert feed.last_seq == 1 and bus.health()["listeners"] == 0


def test_a_listener_that_stops_during_publish_costs_no_other_listener_the_item():
    """A one-shot listener stops itself inside ``publish``: the listener after it still gets that item, and a
    stop called twice never stops another registration of the same callable (session 22 review)."""
    bus = EventBus()
    seen: list[object] = []
    stops: list = []
    once = lambda item: stops[0]()  # noqa: E731
    stops.append(bus.listen([PresenceEvent], once))
    bus.listen([PresenceEvent], seen.append)
    presence = PresenceEvent("approach", 1.0, 3, 4, 1.0, 2.0, 5, 3.0)
    bus.publish(presence)
    assert seen == [presence] and bus.health()["listeners"] == 1
    again = bus.listen([PresenceEvent], seen.append)
    again()
    again()
    bus.publish(presence)
    assert seen == [presence, presence] and bus.health()["listeners"] == 1


async def test_latest_wakes_readers_with_newest_only():
    slot: Latest[int] = Latest()
    assert await slot.next_after(0, timeout=0.01) is None
    reader = asyncio.create_task(slot.next_after(0, timeout=1.0))
    await asyncio.sleep(0)
    slot.publish(0.1, 1)
    slot.publish(0.2, 2)
    first = await reader
    assert first is not None and first.seq >= 1
    newest = await slot.next_after(first.seq - 1, timeout=0.01)
    assert newest is not None and newest.value == 2 and newest.seq == 2


async def test_a_post_from_a_thread_wakes_the_loop_only_for_a_waiting_reader():
    """The projector's render thread posts every frame; the loop is woken only while a reader waits in
    next_after, and a wake-up for an item the reader has already seen does not end its wait."""
    import threading

    loop = asyncio.get_running_loop()
    slot: Latest[int] = Latest()
    heard: list[str] = []
    slot.listen(lambda item: heard.append(threading.current_thread().name))
    wakes: list[object] = []
    original = loop.call_soon_threadsafe

    def counting(callback, *args, **kwargs):
        wakes.append(callback)
        return original(callback, *args, **kwargs)

    loop.call_soon_threadsafe = counting  # type: ignore[method-assign]
    try:
        poster = threading.Thread(target=lambda: [slot.post(loop, 0.1 * k, k) for k in range(5)], name="poster")
        poster.start()
        poster.join()
        assert wakes == [] and slot.get().value == 4 and heard == ["poster"] * 5  # nobody waited: no wake-up
        reader = asyncio.create_task(slot.next_after(5, timeout=2.0))
        ahead = asyncio.create_task(slot.next_after(6, timeout=2.0))  # wants more than the next item
        await asyncio.sleep(0.01)
        threading.Thread(target=slot.post, args=(loop, 0.6, 5)).start()  # item 6: one wake-up, both readers wait
        assert (await reader).value == 5 and len(wakes) == 1
        await asyncio.sleep(0.01)
        assert not ahead.done()  # woken for item 6, which is not above its 6: it waits on
        threading.Thread(target=slot.post, args=(loop, 0.7, 6)).start()
        assert (await ahead).value == 6 and len(wakes) == 2
    finally:
        del loop.call_soon_threadsafe


def test_a_listener_gets_the_current_item_then_every_one_until_it_unlistens():
    slot: Latest[str] = Latest()
    slot.publish(0.0, "before")
    seen: list[tuple[int, str]] = []
    unlisten = slot.listen(lambda item: seen.append((item.seq, item.value)))
    slot.publish(0.1, "a")
    slot.publish(0.2, "b")  # no reader ran in between: a listener still sees both
    unlisten()
    slot.publish(0.3, "after")
    assert seen == [(1, "before"), (2, "a"), (3, "b")]


def test_state_board_snapshot_is_a_copy():
    board = StateBoard()
    board.update("flight", altitude_m=1.2)
    snap = board.snapshot()
    snap["flight"]["altitude_m"] = 0
    assert board.snapshot()["flight"]["altitude_m"] == 1.2


def test_dead_man_lapses_and_stop_clears():
    dm = DeadManCommands()
    dm.command("forward", now=10.0, hold_s=0.5)
    assert dm.active(10.4).name == "forward"
    assert dm.active(10.5) is None and dm.expired == 1
    dm.command("up", now=11.0)
    dm.command("stop", now=11.1)
    assert dm.active(11.2) is None


def test_a_lapse_never_clears_a_command_refreshed_meanwhile():
    """The refresh lands between the lapse's read of the old command and its lock (another thread's step)."""
    dm = DeadManCommands()
    dm.command("forward", now=10.0, hold_s=0.5)
    real = dm._lock

    class RefreshFirst:
        fired = False

        def __enter__(self) -> None:
            if not RefreshFirst.fired:
                RefreshFirst.fired = True
                dm.command("up", now=10.55, hold_s=0.5)
            real.acquire()

        def __exit__(self, *exc: object) -> None:
            real.release()

    dm._lock = RefreshFirst()  # type: ignore[assignment]
    assert dm.active(10.6).name == "up"  # the old one lapsed, the refresh stands
    assert dm.expired == 0 and dm.active(10.7).name == "up"
    assert dm.active(11.05) is None and dm.expired == 1


@pytest.mark.parametrize("hold", [0.0, -1.0, 10.0, math.nan, math.inf])
def test_dead_man_rejects_bad_hold(hold):
    with pytest.raises(ValueError, match="hold"):
        DeadManCommands().command("up", now=0.0, hold_s=hold)


def test_dead_man_rejects_unknown_motion():
    with pytest.raises(ValueError, match="unknown motion 'fly'"):
        DeadManCommands().command("fly", now=0.0)


@given(st.lists(st.tuples(st.sampled_from(["forward", "up", "stop"]), st.floats(0.01, MAX_HOLD_S)), max_size=30))
def test_dead_man_never_outlives_its_hold(commands):
    dm = DeadManCommands()
    now = 0.0
    for name, hold in commands:
        dm.command(name, now=now, hold_s=hold)
        assert dm.active(now + hold) is None
        now += hold + 0.01


def test_touch_event_json_matches_spec_keys_and_nan_is_null():
    obj = _touch(7).to_json()
    assert list(obj) == ["id", "phase", "kind", "t", "x", "y", "u", "v", "depth", "area", "anchor"]
    bad = TouchEvent(1, "up", "tap", 0.0, math.nan, 0, 0, 0, math.inf, 0, 0).to_json()
    assert bad["x"] is None and bad["depth"] is None
    tagged = TouchEvent(1, "up", "tap", 0.0, 1, 2, 0, 0, 0.5, 3, 0.5, extra={"recording": "s1/a"}).to_json()
    assert tagged["recording"] == "s1/a"  # extra keys travel beside the spec keys
