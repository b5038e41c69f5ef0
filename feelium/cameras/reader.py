"""Camera threads and their services: the dedicated worker thread, the rate meter, the frame-fed condition, closing."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

from feelium.cameras.base import Camera
from feelium.cameras.handoff import call_on
from feelium.priority import lower_current_thread

T = TypeVar("T")


class Worker:
    """One dedicated thread for a blocking job (a camera's reads, a pipeline's frames).

    Dedicated, not the loop's shared pool: a camera read that sleeps until its
    next frame, or another service's slow device call, must never make a
    frame wait for a free thread; and one thread per job keeps memory flat
    (each thread that allocates gets its own malloc arena).

    Every such thread moves pixels, so it runs at the bulk-work priority (:mod:`feelium.priority`): when the
    CPU runs short, flight and the headset's replies on the event loop come first.
    """

    def __init__(self, name: str) -> None:
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=name, initializer=lower_current_thread)

    async def call(self, fn: Callable[..., T], *args: Any) -> T:
        return await call_on(self._executor, fn, *args)

    def shutdown(self) -> None:
        """Let the thread end after its current job; never waits (a stuck device read cannot hold shutdown up)."""
        self._executor.shutdown(wait=False, cancel_futures=True)


class RateMeter:
    """Events per second over the last ``window_s`` seconds, read at a given time (time is an input).

    Time-based so that it decays: a source that stops reads 0 once ``window_s``
    has passed without a tick, and reads lower as soon as the gap since its last
    tick grows beyond a usual interval. A count-based window would keep showing
    the last rate of a stalled camera forever.
    """

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self._times: deque[float] = deque()

    def tick(self, t: float) -> None:
        self._times.append(t)
        self._forget(t)

    def rate(self, now: float) -> float:
        """The rate at ``now``: intervals seen in the window over the time they span, the open gap counted once it is late."""
        self._forget(now)
        times = self._times
        if len(times) < 2:
            return 0.0
        intervals = len(times) - 1
        span = times[-1] - times[0]
        if span <= 0:
            return 0.0
        mean = span / intervals
        # the gap since the newest tick counts only beyond one usual interval: a steady source reads its true rate
        late = max(0.0, now - times[-1] - mean)
        return intervals / (span + late)

    def _forget(self, now: float) -> None:
        while self._times and self._times[0] <= now - self.window_s:
            self._times.popleft()


def frame_condition(last_frame_at: float | None, now: float, stale_after_s: float, what: str) -> dict[str, str]:
    """A camera-fed service's own view of its health, for the supervisor (``feelium.service``: condition, reason).

    Starting until the first frame; degraded while frames have stopped coming, so
    health never reports a camera as fine when it is silent.
    """
    if last_frame_at is None:
        return {"condition": "starting", "reason": f"waiting for the first {what} frame"}
    age = now - last_frame_at
    if age > stale_after_s:
        return {"condition": "degraded", "reason": f"no {what} frame for {age:.1f} s"}
    return {"condition": "ok"}


async def close_camera(camera: Camera, worker: Worker) -> None:
    """Close on the camera's own thread, after any in-flight read, then let the thread go."""
    try:
        await worker.call(camera.close)
    finally:
        worker.shutdown()
