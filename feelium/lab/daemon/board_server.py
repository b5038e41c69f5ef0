"""The emulated motor board in its own process, behind a pseudo-terminal the daemon opens as its serial port.

On the blimp the flight controller is another chip: the daemon only frames MSP
requests and parses replies over a UART. Running the simulated board (the
blimp's physics) inside the daemon's process would charge the daemon's CPU and
GIL for it, so the bench runs it here, behind a pty, and the daemon's flight
service takes its ordinary serial path (a pty, as the blimp's UART, so the bench times
the same system calls; ``socket://`` goes through ``transport.BufferedLink`` instead).

``python -m feelium.lab.daemon.board_server`` prints the pty's path, then serves until killed.
"""

from __future__ import annotations

import os
import select
import sys
import time
import tty

from feelium.daemon.config import load_config
from feelium.flight.service import SimOpener
from feelium.flight.transport import ByteLink


def serve(master: int, link: ByteLink) -> None:
    """Answer MSP requests written to the pty with one board that lives as long as the process.

    A reply the daemon's side has no room for is dropped, not waited on: a real board's UART has no flow
    control and overruns, it never stops reading because the Pi is slow. A blocking write here would let a
    starved daemon stall the board, fill the daemon's own output and turn a slow host into a dead link.
    """
    os.set_blocking(master, False)
    while True:
        select.select([master], [], [])
        try:
            data = os.read(master, 4096)
        except BlockingIOError:
            continue
        except OSError:  # EIO: the daemon closed its end
            return
        if not data:
            return
        link.write(data)
        reply = link.read(link.in_waiting)
        if reply:
            try:
                os.write(master, reply)  # a partial write drops the rest, as an overrun would
            except BlockingIOError:
                pass


def main() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)  # bytes pass unchanged: no echo, no line discipline
    config = load_config(None)
    link = SimOpener(config.flight, config.sim.seed, time.monotonic).open()
    print(os.ttyname(slave), flush=True)  # only now: the daemon's first requests must find the board ready
    serve(master, link)


if __name__ == "__main__":
    sys.exit(main())
