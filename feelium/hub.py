"""What the services share inside one daemon: the bus, the newest frames, state and commands.

Services never call each other; they meet here. Everything is newest-wins
or bounded, so a slow reader can only miss data, never hold a writer up.
All methods run on the event loop's thread, except :meth:`Latest.post` (a slot's
one publisher on a worker thread, the projector's frames) and what is said
thread-safe (``hub.motion``).
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from feelium.bus import EventBus
from feelium.motion import DeadManCommands

T = TypeVar("T")


@dataclass(frozen=True)
class Stamped(Generic[T]):
    """A payload with its sequence number and capture time."""

    seq: int
    t: float
    value: T


class Latest(Generic[T]):
    """A newest-wins slot (a video frame, a JPEG, the wearer's face) that readers can await.

    Published on the event loop (:meth:`publish`) or by one worker thread (:meth:`post`); listeners are called
    one item at a time, in order, on the publisher's thread (a lock serialises them with :meth:`listen`'s call).
    """

    def __init__(self) -> None:
        self._item: Stamped[T] | None = None
        self._changed = asyncio.Event()
        self._listeners: list[Callable[[Stamped[T]], None]] = []
        self._listening = threading.Lock()
        self._waiting = 0  # readers in next_after: a post wakes the loop only for them
        self.published = 0

    def publish(self, t: float, value: T) -> Stamped[T]:
        """On the event loop: store, wake the waiting readers, call the listeners."""
        item = self._store(t, value)
        self._wake()
        self._call_listeners(item)
        return item

    def post(self, loop: asyncio.AbstractEventLoop, t: float, value: T) -> Stamped[T]:
        """From the slot's one publishing thread: store and call the listeners here; wake ``loop`` only when a
        reader waits in :meth:`next_after` (one ``call_soon_threadsafe``).

        The item is stored before the waiters are counted, and a reader counts itself before it reads the item:
        a reader this post does not wake has seen the item already. A wake-up that comes after the reader saw
        the item finds nothing newer, and the reader waits on (:meth:`next_after` loops).
        """
        item = self._store(t, value)
        if self._waiting:
            loop.call_soon_threadsafe(self._wake)
        self._call_listeners(item)
        return item

    def _store(self, t: float, value: T) -> Stamped[T]:
        self.published += 1
        item = self._item = Stamped(self.published, t, value)
        return item

    def _wake(self) -> None:
        self._changed.set()
        self._changed = asyncio.Event()

    def _call_listeners(self, item: Stamped[T]) -> None:
        with self._listening:
            for listener in tuple(self._listeners):
                listener(item)

    def listen(self, listener: Callable[[Stamped[T]], None]) -> Callable[[], None]:
        """Call ``listener`` with every item from now on, and with the current one at once; returns the unlisten.

        For a reader that needs every item and does little with each (the touch side records each projector
        canvas): a call inside ``publish`` instead of a task that the loop wakes for every item. It runs on the
        publisher's thread: the projector's render thread for its slots.
        """
        with self._listening:
            self._listeners.append(listener)
            if self._item is not None:
                listener(self._item)
        return lambda: self._listeners.remove(listener)

    def get(self) -> Stamped[T] | None:
        return self._item

    async def next_after(self, seq: int, timeout: float | None = None) -> Stamped[T] | None:
        """The newest item with a sequence number above ``seq``; ``None`` on timeout."""
        self._waiting += 1
        try:
            # asyncio.timeout, not wait_for: on Python 3.11 wait_for wraps the wait in a new task, with its own
            # loop callbacks, each time; every frame's consumers wait here (docs/performance.md).
            async with asyncio.timeout(timeout):
                while True:
                    item = self._item
                    if item is not None and item.seq > seq:
                        return item
                    await self._changed.wait()
        except asyncio.TimeoutError:
            return None
        finally:
            self._waiting -= 1


class StateBoard:
    """Named pieces of live state (touch, presence, altitude, battery...) each service owns one of."""

    def __init__(self) -> None:
        self._parts: dict[str, dict[str, Any]] = {}

    def update(self, part: str, **values: Any) -> None:
        self._parts.setdefault(part, {}).update(values)

    def snapshot(self) -> dict[str, dict[str, Any]]:
        return {name: dict(values) for name, values in self._parts.items()}


@dataclass
class Hub:
    """The meeting point of one daemon's services."""

    bus: EventBus = field(default_factory=EventBus)
    front_video: Latest[Any] = field(default_factory=Latest)  # BGR ndarray frames from the fisheye
    rear_video: Latest[Any] = field(default_factory=Latest)  # gray/BGR debug frames with the touch overlay
    projector_video: Latest[Any] = field(default_factory=Latest)  # what the projector shows
    # the grey skin canvas of each frame shown, stamped as projector_video: the touch side's back-light prediction
    projector_canvas: Latest[Any] = field(default_factory=Latest)
    # the probe's level (feelium.skin.probe) in each frame shown, stamped as projector_video; None: no probe
    projector_probe: Latest[Any] = field(default_factory=Latest)
    face: Latest[Any] = field(default_factory=Latest)  # the wearer's face or avatar from the headset
    motion: DeadManCommands = field(default_factory=DeadManCommands)
    state: StateBoard = field(default_factory=StateBoard)
    rear_scene: Any = None  # the simulator's live scene in sim mode (``feelium.sim.live.LiveRearScene``), else None
    front_lens: dict[str, Any] | None = None  # the front fisheye's lens model as GET /lens serves it; None when off
    clock: Callable[[], float] = time.monotonic
    health: Callable[[], dict[str, Any]] = dict  # replaced by the supervisor with its report
