"""The emulated motor board in its own process, behind a pseudo-terminal the daemon opens as its serial port.

On the blimp the flight controller is another chip: the daemon only frames MSP
requests and parses replies over a UART. Running the simulated board (the
blimp's physics) inside the daemon's process would charge the daemon's CPU and
GIL for it, so the bench runs it here, behind a pty, and the daemon's flight
service takes its ordinary serial path (a pty, not pyserial's ``socket://``:
a socket's ``in_waiting`` says only whether bytes wait, not how many, unlike a UART).

``python -m feelium.lab.daemon.board_server`` prints the pty's path, then serves until killed.
"""

from __future__ import annotations

import os
import sys
import time
import tty

from feelium.daemon.config import load_config
from feelium.flight.service import SimOpener
from feelium.flight.transport import ByteLink


def serve(master: int, link: ByteLink) -> None:
    """Answer MSP requests written to the pty with one board that lives as long as the process."""
    while data := os.read(master, 4096):
        link.write(data)
        reply = link.read(link.in_waiting)
        if reply:
            os.write(master, reply)


def main() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)  # bytes pass unchanged: no echo, no line discipline
    config = load_config(None)
    link = SimOpener(config.flight, config.sim.seed, time.monotonic).open()
    print(os.ttyname(slave), flush=True)  # only now: the daemon's first requests must find the board ready
    serve(master, link)


if __name__ == "__main__":
    sys.exit(main())
