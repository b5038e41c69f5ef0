"""Which event loop the daemon runs on: uvloop where it is installed, asyncio's own otherwise.

Why uvloop: the event loop's thread cannot spread over cores, and on the Pi it was the one thread projected over
its single core (docs/performance.md, issue 16). uvloop runs the loop's own machinery (the selector, the ready
queue, timers, transports, ``call_soon_threadsafe``'s wake-up) in C on libuv; the coroutines, aiohttp's handlers
and every service's code stay the same Python. In ``feelium bench board`` it took about a fifth of the loop
thread's CPU away and halved its median lag. Nothing in the daemon depends on asyncio's private loop internals;
asyncio's loop stays one setting away (``[daemon] event_loop = "asyncio"``) and is what ``auto`` falls back to,
with one log line, where uvloop cannot be imported (it is a dependency, but a hand-made environment may lack it).
"""

from __future__ import annotations

import asyncio
import importlib
import logging
from typing import Literal

from feelium.settings import ConfigError

log = logging.getLogger(__name__)

EventLoopChoice = Literal["auto", "uvloop", "asyncio"]


def new_event_loop(choice: EventLoopChoice) -> tuple[asyncio.AbstractEventLoop, str]:
    """A fresh event loop of the chosen kind and the kind it is (``"uvloop"`` or ``"asyncio"``).

    ``"asyncio"`` is asyncio's own selector loop whatever event loop policy is set, so the setting means the same
    in a process that installed another policy (as the tests can, ``FEELIUM_TEST_EVENT_LOOP``).

    ``uvloop`` chosen explicitly and not importable is a config error naming the key: a setting that asks for
    something must not be quietly ignored. ``auto`` falls back to asyncio and logs why once.
    """
    if choice == "asyncio":
        return asyncio.SelectorEventLoop(), "asyncio"
    try:
        uvloop = importlib.import_module("uvloop")
    except ImportError as exc:
        if choice == "uvloop":
            raise ConfigError("config", "daemon.event_loop", f"uvloop cannot be imported ({exc}); install it or choose 'asyncio'") from exc
        log.warning("uvloop cannot be imported (%s): the daemon runs on asyncio's own event loop", exc)
        return asyncio.SelectorEventLoop(), "asyncio"
    return uvloop.new_event_loop(), "uvloop"


def loop_kind(loop: asyncio.AbstractEventLoop) -> str:
    """``"uvloop"`` or ``"asyncio"``: what a running loop is, for health and benchmarks."""
    return "uvloop" if type(loop).__module__.startswith("uvloop") else "asyncio"
