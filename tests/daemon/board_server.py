"""The emulated motor board on a TCP port, so a real ``feelium run`` process can fly it through ``socket://``.

The board is ``feelium.flight.sim_board.SimMotorBoard`` on the real monotonic
clock, advanced by its own thread as well as by each request, so its 300 ms
link watchdog trips even when the daemon has died and sends nothing. Every
``MSP_SET_MOTOR`` that reaches it is kept with its arrival time: the tests ask
what the motors were told last, and when.
"""

from __future__ import annotations

import socket
import threading
import time

from feelium.flight import messages as m
from feelium.flight.msp import MspParser
from feelium.flight.sim_board import SimMotorBoard, board_with

ADVANCE_EVERY_S = 0.01


class BoardServer:
    """One board, any number of connections in turn (the daemon reconnects after a lost link)."""

    def __init__(self) -> None:
        self.board = SimMotorBoard(board_with(), seed=3, start_t=time.monotonic())
        self.commands: list[tuple[float, tuple[int, ...]]] = []  # (arrival, motors_us) of every MSP_SET_MOTOR
        self._lock = threading.Lock()
        self._closed = threading.Event()
        self._hung_up = threading.Event()  # the connection being served reached its end: every byte sent was read
        self._listener = socket.create_server(("127.0.0.1", 0))
        self._listener.settimeout(0.1)
        self.port = self._listener.getsockname()[1]
        self._threads = [
            threading.Thread(target=self._accept, name="board-accept", daemon=True),
            threading.Thread(target=self._advance, name="board-physics", daemon=True),
        ]
        for thread in self._threads:
            thread.start()

    @property
    def url(self) -> str:
        return f"socket://127.0.0.1:{self.port}"

    def last_command(self) -> tuple[float, tuple[int, ...]] | None:
        with self._lock:
            return self.commands[-1] if self.commands else None

    def wait_hung_up(self, timeout: float) -> bool:
        """Until the daemon's connection has closed and everything it sent has been read (False on timeout).

        A daemon that exits has written its last command, but this board reads it on its own thread, later
        under load: asked before then, ``last_command`` is an older one."""
        return self._hung_up.wait(timeout)

    def motors_us(self) -> tuple[int, ...]:
        with self._lock:
            return tuple(self.board.motors_us)

    def _advance(self) -> None:
        while not self._closed.wait(ADVANCE_EVERY_S):
            with self._lock:
                self.board.advance_to(time.monotonic())

    def _accept(self) -> None:
        while not self._closed.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self._hung_up.clear()
            self._serve(conn)
            self._hung_up.set()

    def _serve(self, conn: socket.socket) -> None:
        parser = MspParser()
        conn.settimeout(0.1)
        with conn:
            while not self._closed.is_set():
                try:
                    data = conn.recv(4096)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not data:
                    return
                reply = bytearray()
                with self._lock:
                    now = time.monotonic()
                    self.board.advance_to(now)
                    for frame in parser.feed(data):
                        if frame.direction != "<":
                            continue
                        reply += self.board.handle(frame)
                        if frame.command == m.MSP_SET_MOTOR:
                            self.commands.append((now, tuple(self.board.motors_us)))
                try:
                    conn.sendall(reply)
                except OSError:
                    return

    def close(self) -> None:
        self._closed.set()
        self._listener.close()
        for thread in self._threads:
            thread.join(1.0)
