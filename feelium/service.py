"""The one interface every daemon service implements.

A service is a thin shell: it owns a backend, feeds its data through a pure
core, and publishes results to the :class:`~feelium.hub.Hub`. The supervisor
(``feelium.daemon.supervisor``) knows nothing else about it.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class Service(Protocol):
    """A supervised part of the daemon.

    - ``run()`` does the work until cancelled; raising means it crashed and
      the supervisor restarts it with backoff.
    - ``stop()`` is called on shutdown before ``run()`` is cancelled, in
      ascending ``stop_order`` (flight is 0, so the motors are safe first);
      it must return quickly (well under a second).
    - ``health()`` is cheap and never raises: counters, rates, last error.
      It may say how the part itself is doing, which the supervisor cannot
      see from the task alone: ``condition`` (``ok``, ``degraded``,
      ``failed`` or ``starting``) and ``reason``; a running service that
      says nothing counts as ok.
    - A service with ``vital = True`` (the flight loop) reports
      ``heartbeat_at`` (the hub's clock at its newest cycle); the systemd
      watchdog is fed only while that is fresh.
    """

    name: str
    stop_order: int

    async def run(self) -> None: ...

    async def stop(self) -> None: ...

    def health(self) -> dict[str, Any]: ...
