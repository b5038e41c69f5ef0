"""System calls and thread CPU per control tick of the MSP client on a real serial path (a pty to the emulated board).

    python benchmarks/flight_syscalls.py pyserial|fast [--ticks 200]

``pyserial`` opens the port as pyserial's own ``Serial`` (every tick before 2026-11-27), ``fast`` as the daemon
does now (:class:`feelium.flight.transport.PosixLink`). Each tick is a poll (the last tick's motor ack waiting)
and a motor command, 20 ms apart; ``os.read``, ``os.write``, ``select.select`` and ``fcntl.ioctl`` are counted
on the calling thread only (the board answers from a thread of its own). For an A/B run both, back to back.
"""

from __future__ import annotations

import argparse
import fcntl
import os
import select
import threading
import time
import tty
from collections import Counter
from collections.abc import Callable
from typing import Any

import serial

from feelium.daemon.config import Config
from feelium.flight import messages as m
from feelium.flight.client import MspClient
from feelium.flight.service import SimOpener
from feelium.flight.transport import WRITE_TIMEOUT_S, open_serial
from feelium.lab.daemon.board_server import serve


def _count_on_this_thread(counts: Counter[str]) -> None:
    me = threading.get_ident()

    def counted(name: str, real: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            if threading.get_ident() == me:
                counts[name] += 1
            return real(*args, **kwargs)

        return call

    for module, name in ((os, "read"), (os, "write"), (select, "select"), (fcntl, "ioctl")):
        setattr(module, name, counted(name, getattr(module, name)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("link", choices=("pyserial", "fast"))
    parser.add_argument("--ticks", type=int, default=200)
    args = parser.parse_args()
    config = Config().flight
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    if args.link == "fast":
        link = open_serial(path, config.baudrate, config.reply_timeout_s)
    else:
        link = serial.serial_for_url(path, baudrate=config.baudrate, timeout=config.reply_timeout_s, write_timeout=WRITE_TIMEOUT_S)
    os.close(slave)
    threading.Thread(target=serve, args=(master, SimOpener(config, 1, time.monotonic).open()), daemon=True).start()
    client = MspClient(link, timeout_s=config.reply_timeout_s)
    client.poll()
    client.send_motors(m.NEUTRAL_MOTORS_US)
    time.sleep(0.02)
    counts: Counter[str] = Counter()
    _count_on_this_thread(counts)
    started = time.thread_time()
    for tick in range(args.ticks):
        client.poll(with_battery=tick % config.battery_every == 0)
        client.send_motors(m.NEUTRAL_MOTORS_US)
        time.sleep(1.0 / config.rate_hz)
    cpu_ms = 1000.0 * (time.thread_time() - started) / args.ticks
    per_tick = {name: round(n / args.ticks, 2) for name, n in sorted(counts.items())}
    print(f"{args.link}: {per_tick}, {sum(counts.values()) / args.ticks:.2f} calls and {cpu_ms:.3f} ms thread CPU a tick; "
          f"timeouts {client.timeouts} (a timed-out tick makes fewer calls)")


if __name__ == "__main__":
    main()
