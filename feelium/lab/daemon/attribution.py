"""Which service spent the process's CPU: thread CPU time, charged to services without touching them.

Three kinds of thread run a service's work, and each is charged differently:

- dedicated threads (``rear-camera``, ``touch-pipeline``, ``front-camera``,
  ``flight-serial``, ``projector-render``, ``thermal``) by their name, from ``/proc/self/task/*/stat``;
- the loop's shared pool (the projector's face decoding, JPEG encoding)
  by the module of the function each job runs, timed with ``time.thread_time``
  around the job in :class:`ChargingExecutor`;
- the event loop's thread by the coroutine a callback resumes, timed around
  each ``asyncio`` handle (:func:`charge_loop_callbacks`).

A simulated device's own work inside a service's call (the MLX90640 simulation
writing its RAM, where the blimp's sensor costs the Pi one I2C read; the
simulated microphone synthesising its tone, where the Pi's ALSA capture hands
over recorded samples) is taken out of that service and charged to
:data:`SIM_DEVICES` (:func:`charged_apart`), which the projection leaves out.

Thread CPU time, not wall time: other processes on the machine delay a thread
but do not add to its CPU time, so a loaded machine inflates these figures far
less than it inflates latencies. Timing each callback costs the loop thread
some CPU of its own, charged to the services like their own work (an
over-estimate on the safe side); :func:`callback_overhead_s` measures it per
callback so the report can state the total.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import os
import threading
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from types import CodeType
from typing import Any

from feelium.cameras.handoff import LoopInbox
from feelium.priority import lower_current_thread

SERVICE_PACKAGES = ("touch", "front_camera", "thermal", "audio", "projector", "flight", "http")
THREAD_SERVICES = {
    "rear-camera": "touch", "touch-pipeline": "touch", "front-camera": "front_camera", "flight-serial": "flight",
    "projector-render": "projector", "thermal": "thermal",
}
HTTP_LIBRARIES = ("aiohttp", "yarl", "multidict")
POOL_PREFIX = "bench-pool"
LOOP_OTHER = "event loop (other)"
JOB_SERVICE = threading.local()  # ``.name``: the service whose job a pool thread runs now (for the numeric split)
OTHER_THREADS = "other threads"
SIM_DEVICES = "simulated devices (not on the Pi)"


def service_of_module(module: str | None) -> str | None:
    """``feelium.projector.renderer`` -> ``projector``; the web server's libraries -> ``http``."""
    if not module:
        return None
    parts = module.split(".")
    if parts[0] == "feelium" and len(parts) > 1 and parts[1] in SERVICE_PACKAGES:
        return parts[1]
    if parts[0] == "feelium" and len(parts) > 1 and parts[1] == "cameras":
        return None  # shared by both cameras: the thread or coroutine above it decides
    return "http" if parts[0] in HTTP_LIBRARIES else None


@functools.lru_cache(maxsize=4096)
def _service_of_code(code: CodeType) -> str | None:
    path = code.co_filename.replace(os.sep, "/")
    for package in SERVICE_PACKAGES:
        if f"/feelium/{package}/" in path:
            return package
    return "http" if any(f"/{lib}/" in path for lib in HTTP_LIBRARIES) else None


def _awaited(coro: Any) -> Iterator[Any]:
    """The chain of coroutines (and async generators) a task is suspended in, outermost first."""
    depth = 0
    while coro is not None and depth < 32:
        yield coro
        coro = getattr(coro, "cr_await", None) or getattr(coro, "ag_await", None)
        depth += 1


def _service_of_callback(callback: Any) -> str:
    """A task step: the first service coroutine in the task's await chain; else the callback's owner's module."""
    owner = getattr(callback, "__self__", None)
    if isinstance(owner, asyncio.Task):
        for coro in _awaited(owner.get_coro()):
            code = getattr(coro, "cr_code", None) or getattr(coro, "ag_code", None)
            service = _service_of_code(code) if code is not None else None
            if service is not None:
                return service
        return LOOP_OTHER
    if owner is None:
        return service_of_module(getattr(callback, "__module__", None)) or LOOP_OTHER
    if isinstance(owner, LoopInbox):  # a worker thread's batch: the service that publishes it
        return _service_of_callback(owner.deliver)
    protocol = getattr(owner, "_protocol", None)  # a transport's read/write callback: charge its protocol
    return service_of_module(type(protocol if protocol is not None else owner).__module__) or LOOP_OTHER


def _service_of_handle(args: tuple[Any, ...]) -> str:
    """The service of the task a future among a callback's arguments will wake (before the callback runs).

    A sleep's timer (``futures._set_result_unless_cancelled(future, ...)``) and a worker thread's result
    (``_chain_future``'s ``_set_state(future, ...)``, by ``call_soon_threadsafe``) are asyncio's own functions,
    but each completes a future one service's task waits on: counted by origin, that is the service's wake-up.
    """
    for arg in args:
        if isinstance(arg, asyncio.Future):
            for waiter, _ in getattr(arg, "_callbacks", None) or ():
                service = _service_of_callback(waiter)
                if service != LOOP_OTHER:
                    return service
    return LOOP_OTHER


class Ledger:
    """CPU seconds per service from the pool and the loop; thread-safe, started and stopped with the window."""

    def __init__(self) -> None:
        self.seconds: dict[tuple[str, str], float] = defaultdict(float)  # (service, "loop" or "pool") -> s
        self.callbacks = 0  # loop callbacks timed while counting
        self.callbacks_by: dict[str, int] = defaultdict(int)  # ...and by the service each was charged to
        # Whether the loop thread's callbacks are charged one by one (asyncio's loop). On uvloop they run in C,
        # unseen: all of the loop thread's time is the remainder, event loop (other), and a service has no loop time.
        self.per_callback = True
        self.counting = False
        self._lock = threading.Lock()

    def add(self, service: str, kind: str, seconds: float) -> None:
        if self.counting:
            with self._lock:
                self.seconds[service, kind] += seconds


class ChargingExecutor(ThreadPoolExecutor):
    """The loop's default executor, charging each job's thread CPU time to the service whose code it runs."""

    def __init__(self, ledger: Ledger, max_workers: int) -> None:
        super().__init__(max_workers=max_workers, thread_name_prefix=POOL_PREFIX, initializer=lower_current_thread)
        self.ledger = ledger

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        target: Any = fn
        if isinstance(fn, functools.partial) and getattr(fn.func, "__name__", "") == "run" and fn.args:
            target = fn.args[0]  # asyncio.to_thread wraps the job in contextvars' Context.run
        service = service_of_module(getattr(target, "__module__", None)) or OTHER_THREADS
        ledger = self.ledger

        def timed() -> Any:
            JOB_SERVICE.name = service
            start = time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                ledger.add(service, "pool", time.thread_time() - start)
                JOB_SERVICE.name = None

        return super().submit(timed)


def charge_loop_callbacks(ledger: Ledger) -> Callable[[], None]:
    """Time every event-loop callback of this process and charge it; returns the function that undoes it."""
    handle = asyncio.events.Handle
    original = handle._run

    def timed_run(self: Any) -> None:
        # Asyncio's own plumbing (a timer, a worker's result) is counted for the service it wakes: the future it
        # completes names that service's task only until it runs. Its CPU stays with event loop (other), as in
        # every run before, so the per-service figures compare.
        woken = _service_of_handle(self._args) if ledger.counting and self._args else LOOP_OTHER
        start = time.thread_time()
        try:
            original(self)
        finally:
            if ledger.counting:
                service = _service_of_callback(self._callback)
                ledger.callbacks += 1
                ledger.callbacks_by[service if service != LOOP_OTHER else woken] += 1
                ledger.add(service, "loop", time.thread_time() - start)

    handle._run = timed_run  # type: ignore[method-assign]
    return lambda: setattr(handle, "_run", original)


def callback_overhead_s(loop: asyncio.AbstractEventLoop, ledger: Ledger, calls: int = 20000) -> float:
    """Thread CPU seconds that timing and charging adds to one loop callback; call before the window opens.

    Measured on a plain callback (charged and then wiped from ``ledger``); a task's step also walks
    its coroutine chain, so the true figure is somewhat higher.
    """
    handle = asyncio.events.Handle(int, (), loop)
    start = time.thread_time()
    for _ in range(calls):
        handle._callback()  # the callback alone, as the loop runs it without the bench
    bare = time.thread_time() - start
    ledger.counting = True
    start = time.thread_time()
    for _ in range(calls):
        handle._run()
    timed = time.thread_time() - start
    ledger.counting = False
    ledger.seconds.clear()
    ledger.callbacks = 0
    ledger.callbacks_by.clear()
    return max(0.0, (timed - bare) / calls)


def thread_cpu() -> dict[str, float]:
    """CPU seconds so far of each live thread of this process, by thread name (Linux ``/proc``; ``{}`` elsewhere)."""
    tick = os.sysconf("SC_CLK_TCK")
    names = {t.native_id: t.name for t in threading.enumerate()}
    out: dict[str, float] = defaultdict(float)
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return {}
    for tid in tids:
        try:
            fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # the thread ended meanwhile
        out[names.get(int(tid), f"native-{tid}")] += (int(fields[11]) + int(fields[12])) / tick
    return dict(out)


def thread_service(name: str) -> str:
    """The service a dedicated thread works for; the pool and the loop are charged per job instead."""
    for prefix, service in THREAD_SERVICES.items():
        if name.startswith(prefix):
            return service
    if name == "MainThread":
        return "MainThread"
    return POOL_PREFIX if name.startswith(POOL_PREFIX) else OTHER_THREADS


def _kind_here() -> str:
    """How the current thread's time is charged: ``loop`` (the event loop's), ``pool`` or ``thread``."""
    name = threading.current_thread().name
    return "loop" if name == "MainThread" else "pool" if name.startswith(POOL_PREFIX) else "thread"


@contextlib.contextmanager
def charged_apart(owner: type, method: str, service: str, ledger: Ledger) -> Iterator[None]:
    """While open, the thread CPU of every outermost call of ``owner.method`` moves from ``service`` to :data:`SIM_DEVICES`.

    For a simulated device a service calls into: the call is timed with the calling thread's CPU clock and
    that time is taken from the service's part of the same kind (loop, pool or thread), so the service's
    own work and the total charged are unchanged; only the device's share moves. On a loop whose callbacks are not
    charged one by one (``ledger.per_callback`` false: uvloop) the loop thread's part is taken from the remainder,
    event loop (other), which :func:`charge` computes net of everything the ledger holds.
    """
    real = getattr(owner, method)
    inside = threading.local()

    @functools.wraps(real)
    def timed(self: Any, *args: Any, **kwargs: Any) -> Any:
        if getattr(inside, "depth", 0):
            return real(self, *args, **kwargs)
        inside.depth = 1
        started = time.thread_time()
        try:
            return real(self, *args, **kwargs)
        finally:
            inside.depth = 0
            spent, kind = time.thread_time() - started, _kind_here()
            if kind != "loop" or ledger.per_callback:
                ledger.add(service, kind, -spent)
            ledger.add(SIM_DEVICES, kind, spent)

    setattr(owner, method, timed)
    try:
        yield
    finally:
        setattr(owner, method, real)


def charge(threads_before: dict[str, float], threads_after: dict[str, float], ledger: Ledger) -> dict[str, dict[str, float]]:
    """CPU seconds per service and kind over the window: ``thread`` (dedicated threads, by name), ``pool``, ``loop``.

    The main thread's and the pool's time that no callback or job accounts for (the selector, the
    loop's own bookkeeping) is ``event loop (other)``; other threads (OpenCV's and numpy's worker
    pools, libraries) are ``other threads``, with each thread's name as its kind.
    """
    out: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
    main = pool = 0.0
    for name, after in threads_after.items():
        spent = max(0.0, after - threads_before.get(name, 0.0))
        service = thread_service(name)
        if service == "MainThread":
            main += spent
        elif service == POOL_PREFIX:
            pool += spent
        elif service == OTHER_THREADS:
            out[service][name] += spent
        else:
            out[service]["thread"] += spent
    for (service, kind), seconds in ledger.seconds.items():
        out[service][kind] += seconds
    out[LOOP_OTHER]["loop"] += max(0.0, main + pool - sum(ledger.seconds.values()))
    return {service: dict(kinds) for service, kinds in out.items()}
