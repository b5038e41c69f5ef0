"""The in-process event bus: producers never wait, slow consumers lose their oldest items.

A touch pipeline must not stall because a headset on bad Wi-Fi reads slowly,
so :meth:`EventBus.publish` is synchronous and O(subscribers): each
subscriber has its own bounded queue, and when it is full the oldest item is
dropped and counted. All methods must be called on the event loop's thread
(services that compute in worker threads publish after awaiting the result),
except :meth:`Subscription.take`, made for a consumer that lives on a thread.
A consumer that only files an item away (a feed that numbers chunks and wakes
its readers) can :meth:`EventBus.listen` instead: called inside ``publish``, it
costs the loop no task step per item.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any, Generic, TypeVar

T = TypeVar("T")
log = logging.getLogger(__name__)


class Subscription(Generic[T]):
    """One consumer's bounded view of the bus."""

    def __init__(self, bus: "EventBus", types: tuple[type, ...] | None, maxsize: int) -> None:
        if maxsize < 1:
            raise ValueError("maxsize must be at least 1")
        self._bus = bus
        self._types = types
        self._items: deque[Any] = deque(maxlen=maxsize)
        self._ready = asyncio.Event()
        self.dropped = 0
        self.delivered = 0

    def wants(self, item: object) -> bool:
        return self._types is None or isinstance(item, self._types)

    def _offer(self, item: Any) -> None:
        if len(self._items) == self._items.maxlen:
            self.dropped += 1  # deque(maxlen) discards the oldest on append
        self._items.append(item)
        self._ready.set()

    def get_nowait(self) -> T | None:
        """The oldest waiting item, or ``None``."""
        if not self._items:
            self._ready.clear()
            return None
        self.delivered += 1
        return self._items.popleft()

    async def get(self, timeout: float | None = None) -> T | None:
        """Wait for the next item; ``None`` on timeout."""
        while not self._items:
            self._ready.clear()
            try:
                async with asyncio.timeout(timeout):
                    await self._ready.wait()
            except asyncio.TimeoutError:
                return None
        return self.get_nowait()

    def drain(self) -> list[T]:
        """Everything waiting, oldest first."""
        items = list(self._items)
        self._items.clear()
        self._ready.clear()
        self.delivered += len(items)
        return items

    def take(self) -> list[T]:
        """Everything waiting, oldest first, taken on any thread: for a consumer that never awaits :meth:`get`.

        Flight's control step runs on its serial thread and reads its events there, at the step,
        so an event published while the thread waited for the tick still counts in that tick.
        ``deque.append`` and ``popleft`` are atomic, so an item the loop publishes meanwhile is
        either taken now or left for the next call; the ready event (which only wakes ``get``) is
        left alone, since clearing it from another thread would race with the loop setting it.
        """
        items: list[T] = []
        pop = self._items.popleft
        while self._items:
            try:
                items.append(pop())
            except IndexError:  # the deque emptied between the check and the pop: nothing is lost
                break
        self.delivered += len(items)
        return items

    def close(self) -> None:
        self._bus._unsubscribe(self)

    def __enter__(self) -> "Subscription[T]":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class EventBus:
    """Typed fan-out of events (``TouchEvent``, ``PresenceEvent``, ...) to subscribers."""

    def __init__(self) -> None:
        self._subscriptions: list[Subscription[Any]] = []
        # replaced, never changed in place: a listener that stops (or adds) one inside ``publish`` cannot make the
        # loop over them skip the next listener
        self._listeners: tuple[tuple[tuple[type, ...], Callable[[Any], None]], ...] = ()
        self.published = 0
        self.listener_errors = 0

    def subscribe(self, types: Iterable[type] | None = None, maxsize: int = 256) -> Subscription[Any]:
        """A new subscription to events of ``types`` (all events when ``None``)."""
        sub: Subscription[Any] = Subscription(self, tuple(types) if types is not None else None, maxsize)
        self._subscriptions.append(sub)
        return sub

    def _unsubscribe(self, sub: Subscription[Any]) -> None:
        if sub in self._subscriptions:
            self._subscriptions.remove(sub)

    def listen(self, types: Iterable[type], listener: Callable[[Any], None]) -> Callable[[], None]:
        """Call ``listener(item)`` inside :meth:`publish` for each item of ``types``; returns what stops it.

        For a consumer whose work per item is a few appends (the speech feed, 25 chunks a second): a
        subscription would wake a task for each item, a loop callback that does nothing but hand it on. The
        listener runs in the producer's call, so it must be quick; one that raises is counted (logged the first
        time) and the producer goes on, since a consumer's fault must not stop the part that publishes."""
        entry = (tuple(types), listener)
        self._listeners += (entry,)

        def stop() -> None:  # by identity: another registration of the same callable stays
            self._listeners = tuple(e for e in self._listeners if e is not entry)

        return stop

    def publish(self, item: object) -> None:
        """Deliver ``item`` to every interested subscriber and listener without waiting."""
        self.published += 1
        for sub in self._subscriptions:
            if sub.wants(item):
                sub._offer(item)
        for types, listener in self._listeners:
            if isinstance(item, types):
                try:
                    listener(item)
                except Exception:
                    self.listener_errors += 1
                    if self.listener_errors == 1:
                        log.exception("a bus listener raised on %s (counted from now on in health)", type(item).__name__)

    def health(self) -> dict[str, Any]:
        return {
            "published": self.published,
            "subscribers": len(self._subscriptions),
            "listeners": len(self._listeners),
            "listener_errors": self.listener_errors,
            "dropped": sum(s.dropped for s in self._subscriptions),
        }
