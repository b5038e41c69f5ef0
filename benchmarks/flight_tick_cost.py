"""Thread CPU per control tick of the flight service on its real path: pyserial over a pty to the emulated board in
another process (`feelium.lab.daemon.board_server`, as `feelium bench board` runs it), the service on an event loop
of its own, nothing else running in the process.

    python benchmarks/flight_tick_cost.py [--seconds 20] [--profile N [--sort cumulative]] [--json FILE]

It reports the serial thread's and the loop thread's CPU per cycle (ms), their sum (what one 50 Hz tick costs
the daemon) and the event loop's callbacks per tick (its wake-ups, asyncio's plumbing included). ``--profile N`` prints cProfile's N most expensive functions of the same work run in one thread instead
(poll, step, send at 50 Hz), to see where a tick's time goes. For an A/B, run it from each worktree, back to back.
"""

from __future__ import annotations

import argparse
import asyncio
import cProfile
import pstats
import subprocess
import sys
import threading
import time

from feelium.daemon.config import Config
from feelium.flight.client import MspClient
from feelium.flight.controller import FlightController
from feelium.flight.service import FlightService, SerialOpener
from feelium.flight.setpoint import setpoint_for_motion
from feelium.hub import Hub
from feelium.lab.report import print_and_save
from loop_callbacks import CallbackCount  # benchmarks/ is the script's own folder


def _serial_thread_cpu() -> float:
    """The serial thread's CPU seconds so far, read from outside it by its CPU clock.

    Read from outside because the thread may be busy with one job for the link's whole life (since session 21
    flight flies a link as one job), so a job submitted to it would wait until the link ends.
    """
    (thread,) = [t for t in threading.enumerate() if t.name.startswith("flight-serial")]
    assert thread.ident is not None
    return time.clock_gettime(time.pthread_getcpuclockid(thread.ident))


async def _run(config: Config, port: str, seconds: float) -> dict[str, float]:
    hub = Hub()
    opener = SerialOpener(port, config.flight.baudrate, config.flight.reply_timeout_s)
    service = FlightService(config.flight, hub, opener)
    task = asyncio.create_task(service.run())
    await asyncio.sleep(2.0)  # warm-up: the link is up, the controller holds
    cycles0, loop0 = service.cycles, time.thread_time()
    serial0 = _serial_thread_cpu()
    with CallbackCount() as count:
        await asyncio.sleep(seconds)
    serial1 = _serial_thread_cpu()
    cycles, loop = service.cycles - cycles0, time.thread_time() - loop0
    overruns = service.overruns
    await service.stop()
    task.cancel()
    with __import__("contextlib").suppress(asyncio.CancelledError):
        await task
    return {
        "cycles": cycles,
        "rate_hz": round(cycles / seconds, 2),
        "overruns": overruns,
        "serial_ms_per_tick": round(1000.0 * (serial1 - serial0) / cycles, 4),
        "loop_ms_per_tick": round(1000.0 * loop / cycles, 4),
        "ms_per_tick": round(1000.0 * (serial1 - serial0 + loop) / cycles, 4),
        "loop_callbacks_per_tick": round(count.calls / cycles, 2),
    }


def _profile(config: Config, port: str, seconds: float, top: int, sort: str = "tottime") -> None:
    """The tick's work in one thread under cProfile: poll, step, send, sleep to the next period."""
    link = SerialOpener(port, config.flight.baudrate, config.flight.reply_timeout_s).open()
    client = MspClient(link, timeout_s=config.flight.reply_timeout_s)
    controller = FlightController(config.flight)
    setpoint = setpoint_for_motion(None, config.flight, soften=False)
    period = 1.0 / config.flight.rate_hz
    profiler = cProfile.Profile(time.thread_time)  # CPU, not wall: sleeping and waiting for replies cost nothing
    next_t = time.monotonic()
    end = next_t + seconds
    profiler.enable()
    cycle = 0
    while time.monotonic() < end:
        telemetry = client.poll(cycle % config.flight.battery_every == 0)
        out = controller.step(time.monotonic(), telemetry, setpoint)
        client.send_motors(out.motors_us)
        cycle += 1
        next_t += period
        time.sleep(max(0.0, next_t - time.monotonic()))
    profiler.disable()
    link.close()
    pstats.Stats(profiler).sort_stats(sort).print_stats(top)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--profile", type=int, default=0, help="print cProfile's N top functions instead")
    parser.add_argument("--sort", default="tottime", help="cProfile's order with --profile (tottime, cumulative)")
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    config = Config()
    board = subprocess.Popen([sys.executable, "-m", "feelium.lab.daemon.board_server"], stdout=subprocess.PIPE, text=True)
    try:
        port = board.stdout.readline().strip() if board.stdout else ""
        if args.profile:
            _profile(config, port, args.seconds, args.profile, args.sort)
            return 0
        report = asyncio.run(_run(config, port, args.seconds))
    finally:
        board.kill()
        board.wait()
    print_and_save(report, args.json)
    return 0


if __name__ == "__main__":
    assert threading.current_thread() is threading.main_thread()
    sys.exit(main())
