"""The flight measurements, each a short simulated flight with a number at the end.

Shared by the tests (which assert the targets) and ``feelium bench flight``
(which reports them with plots). Errors are measured on the simulator's
*true* state, not on what the controller believes, so sensor noise and
estimator error count against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feelium.flight.blimp_model import BlimpParams, DraftParams
from feelium.flight.config import FlightConfig
from feelium.flight.sim_board import BoardParams, board_with
from feelium.flight.setpoint import Setpoint, setpoint_for_motion
from feelium.lab.flight.simulation import Controller, FlightLog, SimFlight
from feelium.motion import DeadManCommands

START_ALTITUDE_M = 1.2
SETTLE_S = 6.0
HOLD_S = 30.0
MOTION_THRESHOLD = {"forward": 0.02, "backward": 0.02, "up": 0.02, "down": 0.02, "turn_left": 3.0, "turn_right": 3.0}
STOPPED_FRACTION = 0.1


def new_flight(
    config: FlightConfig, drafts: bool, seed: int = 1, controller: Controller | None = None, blimp: BlimpParams | None = None,
    command_delay_s: float = 0.0,
) -> SimFlight:
    """A simulated flight at the start altitude; ``blimp`` replaces the body (what-ifs), default the paper's;
    ``command_delay_s`` is how late the board's motors act on a command (the phase sweep)."""
    board = BoardParams(drafts=DraftParams() if drafts else None, command_delay_s=command_delay_s)
    if blimp is not None:
        board = BoardParams(blimp=blimp, drafts=board.drafts, command_delay_s=command_delay_s)
    params = board_with(board, z=START_ALTITUDE_M)
    return SimFlight(config, params, seed=seed, controller=controller)


@dataclass(frozen=True)
class HoldResult:
    altitude_rms_m: float
    heading_rms_deg: float
    roughness: float
    log: FlightLog


def roughness(log: FlightLog, start: int = 0) -> float:
    """Motor-command roughness: sum over motors of squared command changes, per second."""
    commands = np.stack([log[k][start:] for k in ("m1", "m2", "m3", "m4")])
    seconds = log["t"][-1] - log["t"][start]
    return float(np.sum(np.diff(commands, axis=1) ** 2) / max(seconds, 1e-9))


def hold(config: FlightConfig, drafts: bool, seed: int = 1, controller: Controller | None = None, seconds: float = HOLD_S,
         blimp: BlimpParams | None = None) -> HoldResult:
    """Station keeping at the start altitude and heading; RMS errors after settling."""
    flight = new_flight(config, drafts, seed, controller, blimp)
    target = Setpoint(altitude_m=START_ALTITUDE_M, heading_deg=0.0)
    flight.run(SETTLE_S + seconds, target)
    start = int(SETTLE_S * config.rate_hz)
    z = flight.log["z"][start:]
    heading = flight.log["heading"][start:]
    return HoldResult(
        altitude_rms_m=float(np.sqrt(np.mean((z - START_ALTITUDE_M) ** 2))),
        heading_rms_deg=float(np.sqrt(np.mean(wrap_deg_array(heading) ** 2))),
        roughness=roughness(flight.log, start),
        log=flight.log,
    )


def wrap_deg_array(values: np.ndarray) -> np.ndarray:
    return (values + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class StepResult:
    settling_s: float
    overshoot_fraction: float
    t: np.ndarray
    values: np.ndarray
    target: float


def altitude_step(config: FlightConfig, step_m: float = 0.3, seed: int = 1, controller: Controller | None = None, seconds: float = 10.0) -> StepResult:
    """A climb of ``step_m`` in still air: time to stay within 5 % of the step, and overshoot."""
    flight = new_flight(config, False, seed, controller)
    flight.run(SETTLE_S, Setpoint(altitude_m=START_ALTITUDE_M, heading_deg=0.0))
    t0 = flight.t
    target = START_ALTITUDE_M + step_m
    flight.run(seconds, Setpoint(altitude_m=target, heading_deg=0.0))
    first = int(round(t0 * config.rate_hz))
    t = flight.log["t"][first:] - t0
    z = flight.log["z"][first:]
    return _step_result(t, z, START_ALTITUDE_M, target)


def heading_step(config: FlightConfig, step_deg: float = 45.0, seed: int = 1, controller: Controller | None = None, seconds: float = 10.0) -> StepResult:
    flight = new_flight(config, False, seed, controller)
    flight.run(SETTLE_S, Setpoint(altitude_m=START_ALTITUDE_M, heading_deg=0.0))
    t0 = flight.t
    flight.run(seconds, Setpoint(altitude_m=START_ALTITUDE_M, heading_deg=step_deg))
    first = int(round(t0 * config.rate_hz))
    t = flight.log["t"][first:] - t0
    heading = wrap_deg_array(flight.log["heading"][first:])
    return _step_result(t, heading, 0.0, step_deg)


def _step_result(t: np.ndarray, values: np.ndarray, start: float, target: float) -> StepResult:
    size = target - start
    outside = np.abs(values - target) > 0.05 * abs(size)
    settling = float(t[np.nonzero(outside)[0][-1]] + (t[1] - t[0])) if outside.any() else 0.0
    if outside[-1]:
        settling = float("inf")
    overshoot = max(0.0, float(np.max((values - target) * np.sign(size))) / abs(size))
    return StepResult(settling, overshoot, t, values, target)


@dataclass(frozen=True)
class MotionResult:
    command: str
    latency_s: float  # command issued -> body measurably moving
    stop_s: float  # dead man expired -> body below 10 % of its commanded speed
    t: np.ndarray  # seconds since the command was issued
    fraction: np.ndarray  # motion in the commanded direction as a fraction of the commanded rate
    expired_s: float  # when the dead man expired, on the same time axis
    commanded: float  # the commanded rate (m/s, deg/s for turns)
    peak_fraction: float  # the fastest motion while the command was held, as a fraction of the commanded rate
    roughness: float  # motor-command roughness from the command's issue to the end of the run


def _motion_signal(flight: SimFlight, name: str) -> np.ndarray:
    log = flight.log
    if name in ("forward", "backward"):
        return log["u"] * (1 if name == "forward" else -1)
    if name in ("up", "down"):
        return log["w"] * (1 if name == "up" else -1)
    return log["r_dps"] * (1 if name == "turn_right" else -1)


def _first_crossing(t: np.ndarray, signal: np.ndarray, threshold: float, after: float) -> float:
    """When ``signal`` first rises through ``threshold`` after ``after``, interpolated between the
    control-rate samples (the log is 50 Hz; rounding up to the next sample would add up to 20 ms)."""
    above = np.nonzero((t > after) & (signal > threshold))[0]
    if not above.size:
        return float("inf")
    k = int(above[0])
    if k == 0 or t[k - 1] < after or signal[k - 1] >= threshold:
        return float(t[k])
    fraction = (threshold - signal[k - 1]) / (signal[k] - signal[k - 1])
    return float(t[k - 1] + fraction * (t[k] - t[k - 1]))


def motion(
    config: FlightConfig, name: str, hold_s: float = 3.0, seed: int = 1, drafts: bool = False, blimp: BlimpParams | None = None,
    command_delay_s: float = 0.0,
) -> MotionResult:
    """Drive one command through the dead-man path, refreshed every 0.1 s, then let it lapse."""
    flight = new_flight(config, drafts, seed, blimp=blimp, command_delay_s=command_delay_s)
    flight.run(SETTLE_S)
    dead_man = DeadManCommands()
    t_issue = flight.t + flight.period
    last_refresh = t_issue
    dead_man.command(name, t_issue, hold_s=0.5)
    while flight.t < t_issue + hold_s + 3.5:
        now = flight.t + flight.period  # the time of the step about to run
        if now <= t_issue + hold_s and now - last_refresh >= 0.1 - 1e-9:
            dead_man.command(name, now, hold_s=0.5)
            last_refresh = now
        active = dead_man.active(now)
        flight.step(setpoint_for_motion(active.name if active else None, config))
    t_expired = last_refresh + 0.5
    t = flight.log["t"]
    signal = _motion_signal(flight, name)
    latency = _first_crossing(t, signal, MOTION_THRESHOLD[name], t_issue) - t_issue
    cruise = {"forward": config.forward_speed_m_s, "backward": config.forward_speed_m_s, "up": config.climb_rate_m_s,
              "down": config.climb_rate_m_s}.get(name, config.yaw_rate_dps)
    after = np.nonzero(t >= t_expired)[0]
    below = np.abs(signal[after]) < STOPPED_FRACTION * cruise
    # Stopped: the first moment after which it stays below 10 % of cruise for the rest of the run.
    still_moving = np.nonzero(~below)[0]
    if still_moving.size == 0:
        stop = 0.0
    elif still_moving[-1] == below.size - 1:
        stop = float("inf")
    else:
        stop = float(t[after][still_moving[-1] + 1] - t_expired)
    held = (t >= t_issue) & (t <= t_expired)
    issued = int(np.nonzero(t >= t_issue)[0][0])
    fraction = signal / cruise
    return MotionResult(
        name, latency, stop, t - t_issue, fraction, t_expired - t_issue, commanded=cruise,
        peak_fraction=float(np.max(fraction[held])), roughness=roughness(flight.log, max(issued - 1, 0)),
    )


