"""Fly the controller against the simulated board faster than real time, over the real MSP path.

The loop is what the service does, minus the wall clock: advance the
simulated time by one control period, run one MSP exchange (motor command
plus telemetry requests) through :class:`MspClient` and
:class:`SimSerial`, step the controller. Tests and ``feelium bench
flight`` use it; every run with the same seed gives the same numbers.

An optional :class:`LinkFaults` schedule puts a :class:`FaultyLink` between
client and board (stalls, reply lag, unplugged adapter); the loop then
handles a lost link as the service does: no telemetry, the board's watchdog
stops the motors, and the link is reopened with the service's backoff.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import suppress
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from feelium.flight.client import MspClient
from feelium.flight.config import FlightConfig
from feelium.flight.controller import ControlOutput, FlightController
from feelium.flight.faulty_link import FaultyLink, LinkFaults
from feelium.flight.sim_board import BoardParams, SimMotorBoard, SimSerial
from feelium.flight.setpoint import HOLD, Setpoint
from feelium.flight.telemetry import Telemetry
from feelium.flight.transport import ByteLink

SIM_READ_TIMEOUT_S = 0.005  # a blocking read on a faulty link lets at most this much simulated time pass


class Controller(Protocol):
    def step(self, t: float, telemetry: Telemetry | None, setpoint: Setpoint) -> ControlOutput: ...


class ManualClock:
    """Simulated time that only moves when told to."""

    def __init__(self, t: float = 0.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        """Let ``dt`` pass, as a blocking read does in real time."""
        self.t = round(self.t + dt, 9)


@dataclass
class FlightLog:
    """Per-cycle record of truth and control, as arrays once finished."""

    rows: dict[str, list[float]] = field(default_factory=dict)

    def add(self, **values: float) -> None:
        for key, value in values.items():
            self.rows.setdefault(key, []).append(value)

    def __getitem__(self, key: str) -> np.ndarray:
        return np.asarray(self.rows[key], dtype=float)


class SimFlight:
    """One simulated blimp, its board and its controller, stepped in control periods."""

    def __init__(
        self,
        config: FlightConfig,
        board_params: BoardParams,
        seed: int = 1,
        controller: Controller | None = None,
        faults: LinkFaults | None = None,
    ) -> None:
        self.config = config
        self.clock = ManualClock()
        self.board = SimMotorBoard(board_params, seed=seed)
        self.faults = faults
        self.link = self._open_link()
        self.client = self._new_client()
        self.connected = True
        self.link_losses = 0
        self.reconnect_times: list[float] = []
        self._reopen_t = float("inf")
        self._backoff_s = config.reconnect_min_s
        self.controller = controller or FlightController(config)
        self.period = 1.0 / config.rate_hz
        self.log = FlightLog()
        self.cycles = 0
        self.last: ControlOutput | None = None
        self.link_up = True
        self._tick = self._left_at = self.clock.t

    @property
    def t(self) -> float:
        return self.clock.t

    def step(self, setpoint: Setpoint = HOLD) -> ControlOutput:
        self.clock.t = self._tick = self._next_tick()
        self.board.advance_to(self.clock.t)  # physics and the watchdog run whatever the link does
        telemetry = self._poll() if self.link_up else None
        out = self.controller.step(self.clock.t, telemetry, setpoint)
        if self.link_up:
            self._command(out.motors_us)
        self.last = out
        self.cycles += 1
        s = self.board.state
        self.log.add(
            t=self.clock.t,
            x=s.x,
            y=s.y,
            z=s.z,
            w=s.w,
            heading=s.heading_deg,
            r_dps=float(np.degrees(s.r)),
            u=s.u,
            altitude_target=out.altitude_target_m if out.altitude_target_m is not None else np.nan,
            heading_target=out.heading_target_deg if out.heading_target_deg is not None else np.nan,
            m1=out.commands[0],
            m2=out.commands[1],
            m3=out.commands[2],
            m4=out.commands[3],
        )
        self._left_at = self.clock.t
        return out

    def _next_tick(self) -> float:
        """The next period's start on a fixed grid, as the service's loop keeps it.

        A cycle whose exchange ran past the next tick (a silent board) is followed at
        once. If something else moved the clock since the last step (a test stepping
        by hand), the grid restarts from there.
        """
        base = self._tick if self.clock.t == self._left_at else self.clock.t
        return max(round(base + self.period, 9), self.clock.t)

    # ---- the link, as the service runs it ----
    def _open_link(self) -> ByteLink:
        link = SimSerial(self.board, self.clock)
        if self.faults is None:
            return link
        return FaultyLink(link, self.clock, self.faults, sleep=self.clock.sleep, read_timeout_s=SIM_READ_TIMEOUT_S)

    def _new_client(self) -> MspClient:
        return MspClient(self.link, timeout_s=self.config.reply_timeout_s, clock=self.clock)

    def _poll(self) -> Telemetry | None:
        if not self.connected and not self._reopen():
            return None
        try:
            return self.client.poll(with_battery=self.cycles % self.config.battery_every == 0)
        except OSError:
            self._lost()
            return None

    def _command(self, motors_us: tuple[int, ...]) -> None:
        if not self.connected:
            return
        try:
            self.client.send_motors(motors_us)
        except OSError:
            self._lost()

    def _lost(self) -> None:
        """The adapter is gone: close it, try again after the backoff (doubling up to ``reconnect_max_s``)."""
        with suppress(OSError):
            self.link.close()
        self.connected = False
        self.link_losses += 1
        self._schedule_reopen()

    def _schedule_reopen(self) -> None:
        self._reopen_t = self.clock.t + self._backoff_s
        self._backoff_s = min(self._backoff_s * 2.0, self.config.reconnect_max_s)

    def _reopen(self) -> bool:
        if self.clock.t < self._reopen_t:
            return False
        try:
            self.link = self._open_link()
        except OSError:
            self._schedule_reopen()
            return False
        self.client = self._new_client()
        self.connected = True
        self.reconnect_times.append(self.clock.t)
        self._backoff_s = self.config.reconnect_min_s
        return True

    def run(self, seconds: float, setpoint: Setpoint | Callable[[float], Setpoint] = HOLD) -> None:
        """Step for ``seconds``; ``setpoint`` may be a function of the simulated time."""
        end = self.clock.t + seconds - 1e-9
        while self.clock.t < end:
            sp = setpoint(self.clock.t + self.period) if callable(setpoint) else setpoint
            self.step(sp)
