"""Frames between threads, and results back to the event loop, with as few loop wake-ups as the work allows.

A frame that went camera thread -> loop -> pipeline thread -> loop woke the
event loop about nine times (each ``run_in_executor`` round trip is a self-pipe
read, the future's state copy and the task's step, twice, plus the slot's
event). Here the camera thread hands frames straight to the pipeline thread
(:class:`ThreadSlot`), and the pipeline thread hands its results to the loop
through a :class:`LoopInbox`, which wakes the loop once per batch: once per
frame when the loop keeps up, once for several when it lags. Both are bounded,
so a slow side makes the other drop (the camera's frames, newest wins) or wait
(the pipeline, for a loop that has not drained its results), never queue
without bound. A job that must be awaited once per unit of work (the projector's
render; flight's opening, closing and flying of a link) goes to its thread by
:func:`call_on`, which posts the result straight to the awaiting future.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from concurrent.futures import Executor
from typing import Any, Generic, TypeVar

from feelium.cameras.base import Camera, Frame

T = TypeVar("T")


class ThreadSlot:
    """A one-frame hand-over between two threads: a new frame replaces one not yet taken (counted as dropped).

    ``put(..., wait=True)`` makes the producer wait until the slot is empty instead, for sources that deliver on
    demand (a replay as fast as possible), so every frame is processed. After :meth:`end` the consumer still gets
    the frame left in the slot, then ``None``; a producer gets ``False`` and should stop.
    """

    def __init__(self) -> None:
        self._changed = threading.Condition()
        self._frame: Frame | None = None
        self._ended = False
        self.dropped = 0

    def put(self, frame: Frame, *, wait: bool = False) -> bool:
        """Offer ``frame``; ``False`` once the slot has ended (the frame is not kept)."""
        with self._changed:
            if wait:
                self._changed.wait_for(lambda: self._frame is None or self._ended)
            if self._ended:
                return False
            if self._frame is not None:
                self.dropped += 1
            self._frame = frame
            self._changed.notify_all()
            return True

    def take(self) -> Frame | None:
        """The next frame, waiting for one; ``None`` once the slot has ended and is empty."""
        with self._changed:
            self._changed.wait_for(lambda: self._frame is not None or self._ended)
            frame, self._frame = self._frame, None
            self._changed.notify_all()
            return frame

    def end(self) -> None:
        """No more frames: wakes both sides (safe from any thread, any number of times)."""
        with self._changed:
            self._ended = True
            self._changed.notify_all()


def read_into(camera: Camera, slot: ThreadSlot) -> None:
    """Camera-thread job: read frames into ``slot`` until the camera or the slot ends (raises what the camera raises).

    A realtime camera never waits for the consumer (the newest frame wins); one that delivers on demand does.
    """
    try:
        while True:
            frame = camera.read()
            if frame is None or not slot.put(frame, wait=not camera.realtime):
                return
    finally:
        slot.end()


class LoopInbox(Generic[T]):
    """Items a worker thread hands to the event loop, delivered in order and in batches: one wake-up per batch.

    The first item of a batch schedules one ``call_soon_threadsafe``; items posted before the loop runs it join
    that batch. At ``limit`` undelivered items :meth:`post` waits for the loop (back-pressure instead of a queue
    that grows while the loop is stuck). After :meth:`close` posts are dropped and never wait.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, deliver: Callable[[list[T]], None], limit: int = 30) -> None:
        self._loop = loop
        self.deliver = deliver  # public: the bench charges each batch to the service that ``deliver`` belongs to
        self._limit = limit
        self._changed = threading.Condition()
        self._items: list[T] = []
        self._closed = False
        self.wakeups = 0  # batches scheduled on the loop
        self.posted = 0

    def post(self, item: T) -> None:
        """From the worker thread: queue ``item`` for the loop, waking it only if no batch is pending."""
        with self._changed:
            self._changed.wait_for(lambda: len(self._items) < self._limit or self._closed)
            if self._closed:
                return
            self._items.append(item)
            self.posted += 1
            first = len(self._items) == 1
            if first:
                self.wakeups += 1
        if first:
            self._loop.call_soon_threadsafe(self._drain)

    def close(self) -> None:
        """No more deliveries; a worker waiting in :meth:`post` goes on at once."""
        with self._changed:
            self._closed = True
            self._items.clear()
            self._changed.notify_all()

    def _drain(self) -> None:
        """On the loop: deliver the whole batch."""
        with self._changed:
            items, self._items = self._items, []
            closed = self._closed
            self._changed.notify_all()
        if items and not closed:
            self.deliver(items)


async def call_on(executor: Executor, fn: Callable[..., T], *args: Any) -> T:
    """``fn(*args)`` on ``executor``'s thread, awaited: ``run_in_executor`` at about half its cost on the loop.

    ``run_in_executor`` chains two futures: the executor's (with its condition variable) calls back on the
    worker thread, which schedules the copy of its state into an asyncio future, whose completion then
    schedules the task. Here the worker posts the outcome straight into the awaited future (one
    ``call_soon_threadsafe``, as before), and the chain's bookkeeping goes: per hand-off on uvloop, 41-44 ->
    19-25 us of the loop thread and 64-68 -> 37-45 us of the process on this machine
    (``benchmarks/handoff_cost.py``; docs/performance.md, session 16), paid 30 times a second by the projector
    (and 50 by flight's ticks until session 21, since when a link is flown as one job). The rest is as before: jobs run
    one after another on the executor's threads, an exception is raised to the awaiting task, and a
    cancelled wait cancels a job that has not started (one that runs finishes; its outcome is dropped).
    """
    loop = asyncio.get_running_loop()
    outcome: asyncio.Future[T] = loop.create_future()
    job = executor.submit(_run_and_post, loop, outcome, fn, args)
    try:
        return await outcome
    except asyncio.CancelledError:
        job.cancel()
        raise


def _run_and_post(loop: asyncio.AbstractEventLoop, outcome: asyncio.Future[Any], fn: Callable[..., Any], args: tuple[Any, ...]) -> None:
    """Worker-thread side of :func:`call_on` (a closed loop raises here, into the executor's unread future)."""
    try:
        result = fn(*args)
    except BaseException as exc:  # as run_in_executor: whatever the job raised reaches the awaiting task
        loop.call_soon_threadsafe(_settle, outcome, None, exc)
    else:
        loop.call_soon_threadsafe(_settle, outcome, result, None)


def _settle(outcome: asyncio.Future[Any], result: Any, exc: BaseException | None) -> None:
    """On the loop: complete the awaited future, unless the wait was cancelled meanwhile."""
    if outcome.cancelled():
        return
    if exc is None:
        outcome.set_result(result)
    else:
        outcome.set_exception(exc)
