"""The safety flight: one scripted flight per plant that measures every safety goal of the controller.

It is what a careful user does to a blimp they do not trust: hover and
listen to the motors, drive forward and say ``stop``, drive and let go,
back up, turn both ways, climb into the ceiling limit and sink to the floor
limit, all through the dead-man path the headset uses (refreshed every
0.1 s). Everything is measured on the simulator's *true* state. The goals
(``docs/flight-robustness.md``):

- stopped (surge speed under 5 cm/s and yaw rate under 3 deg/s, and staying so)
  within 1.0 s of an explicit ``stop`` and within 1.5 s of the last refresh;
- never over 120 % of the commanded speed or turn rate;
- never outside [altitude_min, altitude_max] by more than 10 cm;
- at most 0.5 direction reversals per second of either horizontal motor in hover.

It also reports how far the hover wandered, which no goal of the issue bounds: the
whole drift (``hover_drift_m``) and its part along the body's axis
(``hover_surge_drift_m``). Only the latter is the controller's: the blimp has no
lateral motor, so a cross draft carries it sideways whatever it does. The surge loop
rests inside a speed band, not on a place, and a change that buys calm motors with
weaker corrections shows up there first.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from feelium.flight.config import FlightConfig
from feelium.flight.faulty_link import LinkFaults, Window
from feelium.flight.setpoint import setpoint_for_motion
from feelium.flight.sim_board import BoardParams, SensorParams, board_with
from feelium.lab.flight.plants import MILD_DRAFTS, Plant
from feelium.lab.flight.simulation import Controller, SimFlight
from feelium.motion import DeadManCommands

START_ALTITUDE_M = 1.2
SETTLE_S = 6.0
HOVER_S = 15.0
HELD_S = 3.0
OBSERVE_S = 3.0
REFRESH_S = 0.1
HOLD_S = 0.5
STOPPED_SPEED_M_S = 0.05
STOPPED_YAW_DPS = 3.0

GOALS = {"stop_s": 1.0, "lapse_s": 1.5, "speed_peak_fraction": 1.2, "turn_peak_fraction": 1.2,
         "altitude_excursion_m": 0.1, "hover_reversals_per_s": 0.5}
# Reported beside the goals, with no limit of its own (see the module's docstring).
REPORTED = ("hover_drift_m", "hover_surge_drift_m")


@dataclass
class SafetyResult:
    """The worst figure of each goal over the flight, and each manoeuvre's own."""

    plant: str
    stop_s: float = 0.0  # explicit stop -> stopped, worst manoeuvre
    lapse_s: float = 0.0  # last refresh -> stopped, worst manoeuvre
    speed_peak_fraction: float = 0.0
    turn_peak_fraction: float = 0.0
    altitude_excursion_m: float = 0.0  # furthest outside [altitude_min, altitude_max]
    hover_reversals_per_s: float = 0.0
    hover_drift_m: float = 0.0  # furthest horizontal distance from where the hover began, over the hover
    hover_surge_drift_m: float = 0.0  # the same along the body's axis at the hover's start (what the surge can correct)
    manoeuvres: dict[str, dict[str, float]] = field(default_factory=dict)

    def failures(self) -> dict[str, float]:
        """The goals this flight missed, with the figure."""
        return {key: getattr(self, key) for key, limit in GOALS.items() if not getattr(self, key) <= limit}

    def figures(self) -> dict[str, float]:
        """Every goal's figure and the reported ones."""
        return {key: getattr(self, key) for key in (*GOALS, *REPORTED)}


def reversals_per_s(commands: np.ndarray, deadband: float, seconds: float) -> float:
    """Direction changes of one motor per second: sign changes between commands that spin it (outside the deadband)."""
    spinning = commands[np.abs(commands) > deadband]
    if spinning.size < 2:
        return 0.0
    return float(np.count_nonzero(np.diff(np.sign(spinning)) != 0) / max(seconds, 1e-9))


def farthest_from_start(x: np.ndarray, y: np.ndarray) -> float:
    """The largest horizontal distance from the first position of a track (0 for an empty one)."""
    if x.size == 0:
        return 0.0
    return float(np.max(np.hypot(x - x[0], y - y[0])))


def farthest_along(x: np.ndarray, y: np.ndarray, heading_deg: float) -> float:
    """The largest distance from a track's first position along the direction ``heading_deg`` (either way)."""
    if x.size == 0:
        return 0.0
    h = np.radians(heading_deg)
    return float(np.max(np.abs((x - x[0]) * np.cos(h) + (y - y[0]) * np.sin(h))))


def stopped_after(t: np.ndarray, u: np.ndarray, r_dps: np.ndarray, since: float, until: float) -> float:
    """Seconds from ``since`` until surge and yaw rate are below the stop thresholds for good (up to ``until``)."""
    window = (t >= since) & (t <= until)
    moving = (np.abs(u[window]) >= STOPPED_SPEED_M_S) | (np.abs(r_dps[window]) >= STOPPED_YAW_DPS)
    times = t[window]
    if not moving.any():
        return 0.0
    last = int(np.nonzero(moving)[0][-1])
    if last == moving.size - 1:
        return float("inf")
    return float(times[last + 1] - since)


class _Pilot:
    """Drives a SimFlight through the dead-man path, as the headset does."""

    def __init__(self, flight: SimFlight, config: FlightConfig) -> None:
        self.flight, self.config = flight, config
        self.dead_man = DeadManCommands()
        self.last_refresh = -np.inf

    def fly(self, seconds: float, refresh: str | None = None, until_refresh: float | None = None) -> None:
        """Step ``seconds``; refresh ``refresh`` every 0.1 s while before ``until_refresh``."""
        end = self.flight.t + seconds - 1e-9
        last = -np.inf
        while self.flight.t < end:
            now = self.flight.t + self.flight.period
            if refresh and (until_refresh is None or now <= until_refresh) and now - last >= REFRESH_S - 1e-9:
                self.dead_man.command(refresh, now, hold_s=HOLD_S)
                last = self.last_refresh = now
            active = self.dead_man.active(now)
            self.flight.step(setpoint_for_motion(active.name if active else None, self.config))

    def command(self, name: str) -> None:
        self.dead_man.command(name, self.flight.t + self.flight.period, hold_s=HOLD_S)


def safety_flight(config: FlightConfig, plant: Plant, seed: int = 1, controller: Controller | None = None,
                  flow: bool = True, report: Callable[[str], None] | None = None,
                  command_delay_s: float = 0.0, lag_s: float = 0.0) -> SafetyResult:
    """Fly the whole script on ``plant``; ``flow=False`` is a board without the optical-flow sensor;
    ``command_delay_s`` is how late the board's motors act on a command (the phase sweep); ``lag_s`` how late every
    reply reaches the Pi (a USB serial adapter's few ms, up to its 16 ms latency timer)."""
    board = board_with(BoardParams(blimp=plant.blimp, drafts=MILD_DRAFTS, sensors=SensorParams(flow_fitted=flow),
                                   command_delay_s=command_delay_s), z=START_ALTITUDE_M)
    flight = SimFlight(config, board, seed=seed, controller=controller, faults=LinkFaults(lag_s=lag_s) if lag_s else None)
    pilot = _Pilot(flight, config)
    result = SafetyResult(plant.name)
    deadband = plant.blimp.horizontal_motor.deadband

    pilot.fly(SETTLE_S)
    start = flight.cycles
    pilot.fly(HOVER_S)
    m1, m2 = flight.log["m1"][start:], flight.log["m2"][start:]
    result.hover_reversals_per_s = max(reversals_per_s(m1, deadband, HOVER_S), reversals_per_s(m2, deadband, HOVER_S))
    x, y = flight.log["x"][start:], flight.log["y"][start:]
    result.hover_drift_m = farthest_from_start(x, y)
    result.hover_surge_drift_m = farthest_along(x, y, float(flight.log["heading"][start]))

    for name, ending in (("forward", "stop"), ("forward", "lapse"), ("backward", "stop"),
                         ("turn_right", "stop"), ("turn_left", "lapse")):
        t_issue = flight.t
        if ending == "stop":
            pilot.fly(HELD_S, refresh=name)
            t_end = flight.t
            pilot.command("stop")
            pilot.fly(OBSERVE_S)
        else:
            pilot.fly(HELD_S + HOLD_S + OBSERVE_S, refresh=name, until_refresh=t_issue + HELD_S)
            t_end = pilot.last_refresh
        t, rows = flight.log["t"], flight.log
        held = (t > t_issue) & (t <= t_end)
        if name in ("forward", "backward"):
            peak = float(np.max(np.abs(rows["u"][held]))) / config.forward_speed_m_s
            result.speed_peak_fraction = max(result.speed_peak_fraction, peak)
        else:
            peak = float(np.max(np.abs(rows["r_dps"][held]))) / config.yaw_rate_dps
            result.turn_peak_fraction = max(result.turn_peak_fraction, peak)
        stop = stopped_after(t, rows["u"], rows["r_dps"], t_end, flight.t)
        if ending == "stop":
            result.stop_s = max(result.stop_s, stop)
        else:
            result.lapse_s = max(result.lapse_s, stop)
        result.manoeuvres[f"{name}-{ending}"] = {"peak_fraction": round(peak, 3), "stop_s": round(stop, 3)}

    for name, seconds in (("up", 9.0), ("down", 12.0)):
        pilot.fly(seconds, refresh=name)
        pilot.fly(3.0)
    z = flight.log["z"][int(SETTLE_S * config.rate_hz):]
    result.altitude_excursion_m = float(max(0.0, np.max(z) - config.altitude_max_m, config.altitude_min_m - np.min(z)))
    if report is not None:
        report(f"{plant.name}: " + ", ".join(f"{k}={v:.3g}" for k, v in result.figures().items()))
    return result


# A held command through a link fault (issue 13, point 3): the kind, seconds into the hold it starts, how long.
FAULT_HELD_S = 12.0
HELD_FAULTS = (("stall", 0.5, 3.0), ("stall", 3.0, 3.0), ("drop", 0.5, 3.0), ("drop", 3.0, 1.0))
# After a fault the body is judged against the altitude limits only from its return from the furthest it went outside
# them within this long of the fault's end (``back_inside_limits``): the climb a fault started, carried on.
AFTERMATH_S = 3.0


def held_through_fault(config: FlightConfig, plant: Plant, command: str, kind: str, at_s: float, long_s: float,
                       seed: int = 1, lag_s: float = 0.0) -> dict[str, float]:
    """Hold ``command`` for ``FAULT_HELD_S`` with the board stalled (``kind`` "stall") or the link unplugged ("drop")
    for ``long_s`` from ``at_s`` into it, every reply ``lag_s`` late throughout, then let go: the hold's speed or turn peak (fraction of the command), the
    stop after the release (s: the command ends at once, as an explicit ``stop`` ends it, so its goal is ``stop_s``,
    not the lapse's, which counts the dead-man's 0.5 s hold) and the highest altitude (m).

    The safety flight has no fault; this is what a fault hides from it. The watchdog stops the motors, the body floats
    up, and the held command resumes on fresh telemetry with whatever the outage taught the estimators: one window of
    flow noise once assured a brake of the box's strongest, and a correction against the command escalated as if it
    had pushed since the command began (docs/flight-robustness.md, session 33)."""
    if kind not in ("stall", "drop"):
        raise ValueError(f"a held command's fault is a stall or a drop, not {kind!r}")
    board = board_with(BoardParams(blimp=plant.blimp, drafts=MILD_DRAFTS), z=START_ALTITUDE_M)
    window = (Window(SETTLE_S + at_s, SETTLE_S + at_s + long_s),)
    faults = LinkFaults(stalls=window, lag_s=lag_s) if kind == "stall" else LinkFaults(drops=window, lag_s=lag_s)
    flight = SimFlight(config, board, seed=seed, faults=faults)
    flight.run(SETTLE_S)
    flight.run(FAULT_HELD_S, setpoint_for_motion(command, config))
    released = flight.t
    flight.run(OBSERVE_S + 1.0)
    t, u, r, z = flight.log["t"], flight.log["u"], flight.log["r_dps"], flight.log["z"]
    held = (t > SETTLE_S) & (t <= released)
    surge = command in ("forward", "backward")
    peak = float(np.max(np.abs((u if surge else r)[held]))) / (config.forward_speed_m_s if surge else config.yaw_rate_dps)
    returned_s, excursion_m = back_inside_limits(t, z, SETTLE_S + at_s + long_s, config.altitude_min_m, config.altitude_max_m,
                                                 GOALS["altitude_excursion_m"])
    return {"speed_peak_fraction" if surge else "turn_peak_fraction": peak,
            "stop_s": stopped_after(t, u, r, released, flight.t), "highest_m": float(np.max(z)),
            "returned_s": returned_s, "excursion_after_return_m": excursion_m}


def back_inside_limits(t: np.ndarray, z: np.ndarray, since: float, low: float, high: float,
                       tolerance: float) -> tuple[float, float]:
    """After a fault that ended at ``since``: how long the body took to come back within ``tolerance`` of [``low``,
    ``high``] (the goal's) from the furthest it went outside them in the fault's aftermath (``AFTERMATH_S``), and how
    far outside it went from its return on (both ``inf`` if it never came back).

    The rise *during* a fault is the board's (its watchdog sets the motors neutral and the body is positively buoyant:
    the contract's), and so is the climb it carries on with for a moment after it: a heavy weak corner rising at 0.6 m/s
    when the link returns has too little authority to stop short of the ceiling. The highest altitude mixes that with
    what the controller did after; the limit goal ("never outside by more than 10 cm, reconnects included") is the
    controller's once it has brought the body back. With every reply 30 ms late a light strong corner that had come
    back under the ceiling limit climbed into the room's ceiling (3.0 m, 0.4 m over the limit) after the release, with
    the link up for 8 s (docs/flight-robustness.md, session 35)."""
    outside = np.maximum(np.maximum(z - high, low - z), 0.0)
    aftermath = (t >= since) & (t <= since + AFTERMATH_S)
    start = int(np.argmax(np.where(aftermath, outside, -1.0))) if aftermath.any() else int(np.searchsorted(t, since))
    inside = (np.arange(t.size) >= start) & (outside <= tolerance)
    if not inside.any():
        return float("inf"), float("inf")
    back = int(np.argmax(inside))
    return float(t[back] - since), float(np.max(outside[back:]))
