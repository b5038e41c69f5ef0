"""Fly the controller against the simulated board faster than real time, over the real MSP path.

The loop is what the service does, minus the wall clock: advance the
simulated time by one control period, run one MSP exchange (motor command
plus telemetry requests) through :class:`MspClient` and
:class:`SimSerial`, step the controller. Tests and ``feelium bench
flight`` use it; every run with the same seed gives the same numbers.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from feelium.flight.client import MspClient
from feelium.flight.config import FlightConfig
from feelium.flight.controller import ControlOutput, FlightController
from feelium.flight.sim_board import BoardParams, SimMotorBoard, SimSerial
from feelium.flight.setpoint import HOLD, Setpoint
from feelium.flight.telemetry import Telemetry


class Controller(Protocol):
    def step(self, t: float, telemetry: Telemetry | None, setpoint: Setpoint) -> ControlOutput: ...


class ManualClock:
    """Simulated time that only moves when told to."""

    def __init__(self, t: float = 0.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


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
        self, config: FlightConfig, board_params: BoardParams, seed: int = 1, controller: Controller | None = None
    ) -> None:
        self.config = config
        self.clock = ManualClock()
        self.board = SimMotorBoard(board_params, seed=seed)
        self.link = SimSerial(self.board, self.clock)
        self.client = MspClient(self.link, timeout_s=config.reply_timeout_s, clock=self.clock)
        self.controller = controller or FlightController(config)
        self.period = 1.0 / config.rate_hz
        self.log = FlightLog()
        self.cycles = 0
        self.last: ControlOutput | None = None
        self.link_up = True

    @property
    def t(self) -> float:
        return self.clock.t

    def step(self, setpoint: Setpoint = HOLD) -> ControlOutput:
        self.clock.t = round(self.clock.t + self.period, 9)
        telemetry = None
        if self.link_up:
            telemetry = self.client.poll(with_battery=self.cycles % self.config.battery_every == 0)
        else:
            self.board.advance_to(self.clock.t)
        out = self.controller.step(self.clock.t, telemetry, setpoint)
        if self.link_up:
            self.client.send_motors(out.motors_us)
        self.last = out
        self.cycles += 1
        s = self.board.state
        self.log.add(
            t=self.clock.t,
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
        return out

    def run(self, seconds: float, setpoint: Setpoint | Callable[[float], Setpoint] = HOLD) -> None:
        """Step for ``seconds``; ``setpoint`` may be a function of the simulated time."""
        end = self.clock.t + seconds - 1e-9
        while self.clock.t < end:
            sp = setpoint(self.clock.t + self.period) if callable(setpoint) else setpoint
            self.step(sp)
