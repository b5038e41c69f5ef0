"""Frames between threads and results back to the loop: newest wins, nothing lost on demand, one wake-up per batch,
one post per awaited job."""

from __future__ import annotations

import asyncio
import threading

import numpy as np
import pytest

from feelium.cameras.base import Frame
from feelium.cameras.handoff import LoopInbox, ThreadSlot, call_on, read_into


def _frame(i: int) -> Frame:
    return Frame(t=float(i), image=np.zeros((2, 2), np.uint8))


def test_slot_keeps_the_newest_frame_and_counts_the_ones_it_replaced():
    slot = ThreadSlot()
    for i in range(5):
        assert slot.put(_frame(i))
    taken = slot.take()
    assert taken is not None and taken.t == 4.0
    assert slot.dropped == 4
    slot.end()
    assert slot.take() is None


def test_slot_hands_over_what_is_left_before_reporting_the_end_and_refuses_more():
    slot = ThreadSlot()
    slot.put(_frame(1))
    slot.end()
    assert not slot.put(_frame(2))
    first = slot.take()
    assert first is not None and first.t == 1.0
    assert slot.take() is None


class ListCamera:
    name = "list"

    def __init__(self, n: int, realtime: bool) -> None:
        self.frames = [_frame(i) for i in range(n)]
        self.realtime = realtime

    def read(self) -> Frame | None:
        return self.frames.pop(0) if self.frames else None

    def close(self) -> None:
        pass


def test_an_on_demand_source_loses_nothing_for_a_slow_consumer():
    slot = ThreadSlot()
    reader = threading.Thread(target=read_into, args=(ListCamera(20, realtime=False), slot))
    reader.start()
    seen = []
    while (frame := slot.take()) is not None:
        seen.append(frame.t)
    reader.join(5.0)
    assert seen == [float(i) for i in range(20)] and slot.dropped == 0


class RaisingCamera(ListCamera):
    def read(self) -> Frame | None:
        if not self.frames:
            raise OSError("unplugged")
        return super().read()


def test_a_failing_camera_ends_the_slot_and_raises():
    slot = ThreadSlot()
    with pytest.raises(OSError, match="unplugged"):
        read_into(RaisingCamera(2, realtime=True), slot)
    assert slot.take() is not None  # the newest frame is still handed over
    assert slot.take() is None


def test_ending_the_slot_releases_a_producer_waiting_for_the_consumer():
    slot = ThreadSlot()
    reader = threading.Thread(target=read_into, args=(ListCamera(5, realtime=False), slot))
    reader.start()
    assert slot.take() is not None
    slot.end()  # the producer waits for the slot to empty: it must give up instead
    reader.join(5.0)
    assert not reader.is_alive()


class FakeLoop:
    """Counts the wake-ups a thread asks for; runs them when the test says the loop gets its turn."""

    def __init__(self) -> None:
        self.scheduled: list = []
        self.wakeups = 0

    def call_soon_threadsafe(self, callback) -> None:
        self.scheduled.append(callback)
        self.wakeups += 1

    def run_once(self) -> None:
        callbacks, self.scheduled = self.scheduled, []
        for callback in callbacks:
            callback()


def test_a_batch_posted_before_the_loop_runs_costs_one_wake_up_in_order():
    loop, batches = FakeLoop(), []
    inbox = LoopInbox(loop, batches.append)
    for i in range(5):
        inbox.post(i)
    loop.run_once()
    assert batches == [[0, 1, 2, 3, 4]] and loop.wakeups == inbox.wakeups == 1


def test_one_wake_up_per_item_when_the_loop_keeps_up():
    loop, batches = FakeLoop(), []
    inbox = LoopInbox(loop, batches.append)
    for i in range(10):
        inbox.post(i)
        loop.run_once()
    assert batches == [[i] for i in range(10)] and loop.wakeups == 10


def test_a_full_inbox_makes_the_worker_wait_for_the_loop():
    loop, batches = FakeLoop(), []
    inbox = LoopInbox(loop, batches.append, limit=3)
    for i in range(3):
        inbox.post(i)
    worker = threading.Thread(target=inbox.post, args=(3,))
    worker.start()
    worker.join(0.2)
    assert worker.is_alive()  # waiting: the loop has not taken the three yet
    loop.run_once()
    worker.join(5.0)
    loop.run_once()
    assert batches == [[0, 1, 2], [3]] and loop.wakeups == 2


def test_closing_releases_a_waiting_worker_and_drops_what_is_left():
    loop, batches = FakeLoop(), []
    inbox = LoopInbox(loop, batches.append, limit=1)
    inbox.post(0)
    worker = threading.Thread(target=inbox.post, args=(1,))
    worker.start()
    inbox.close()
    worker.join(5.0)
    inbox.post(2)
    loop.run_once()
    assert not worker.is_alive() and batches == [] and loop.wakeups == 1


async def test_a_real_loop_gets_the_batch_in_order():
    batches: list[list[int]] = []
    inbox: LoopInbox[int] = LoopInbox(asyncio.get_running_loop(), batches.append)
    await asyncio.to_thread(lambda: [inbox.post(i) for i in range(5)])
    await asyncio.sleep(0)
    assert [i for batch in batches for i in batch] == [0, 1, 2, 3, 4]


async def test_a_job_called_on_a_thread_returns_its_result_in_order_and_raises_its_error():
    from concurrent.futures import ThreadPoolExecutor

    ran_on: list[str] = []

    def job(i: int) -> int:
        ran_on.append(threading.current_thread().name)
        return i * i

    with ThreadPoolExecutor(1, thread_name_prefix="serial") as executor:
        assert [await call_on(executor, job, i) for i in range(4)] == [0, 1, 4, 9]
        with pytest.raises(ZeroDivisionError):
            await call_on(executor, lambda: 1 / 0)
    assert ran_on == ["serial_0"] * 4


async def test_a_cancelled_wait_cancels_a_job_not_started_and_drops_a_running_ones_outcome():
    from concurrent.futures import ThreadPoolExecutor

    release, started, ran = threading.Event(), threading.Event(), []

    def blocking() -> str:
        started.set()
        release.wait(5.0)
        ran.append("blocking")
        return "late"

    with ThreadPoolExecutor(1) as executor:
        running = asyncio.ensure_future(call_on(executor, blocking))
        queued = asyncio.ensure_future(call_on(executor, ran.append, "queued"))
        while not started.is_set():
            await asyncio.sleep(0.001)
        running.cancel()
        queued.cancel()
        await asyncio.sleep(0.01)  # the tasks take their cancellation (as with run_in_executor, on the loop's next turn)
        release.set()
        for task in (running, queued):
            with pytest.raises(asyncio.CancelledError):
                await task
        assert await call_on(executor, len, "abc") == 3  # the thread goes on with the next job
    assert ran == ["blocking"]  # the queued job never ran; the running one finished, its result dropped
