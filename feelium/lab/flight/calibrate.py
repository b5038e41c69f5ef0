"""`feelium calibrate flight`: fly the calibration script on a board, fit the plant, write the config and plots.

The shell around two pure parts: the script (``calibration_pilot.py``) and the
fit (``feelium/flight/sysid.py``). It drives any MSP board through the same
``MspClient`` the service uses: a serial port in real time, or the simulated
board on a manual clock (minutes of flight in seconds, what the tests and
the plant bench use). Whatever ends the flight (the script's end, ``stop``,
Ctrl-C or SIGTERM, an exception, lost telemetry) the last thing written to
the board is neutral on every motor.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from feelium.flight.client import MspClient
from feelium.flight.config import FlightConfig
from feelium.flight.mixer import command_for_thrust, to_microseconds
from feelium.flight.sim_board import BoardParams, SensorParams, SimMotorBoard, SimSerial, board_with
from feelium.flight.sysid import Estimate, FlightRecord, PlantFit, identify
from feelium.flight.telemetry import Telemetry
from feelium.flight.transport import ByteLink
from feelium.lab.flight.calibration_pilot import CalibrationPilot
from feelium.lab.flight.simulation import ManualClock

MAX_FLIGHT_S = 360.0  # the script is 210-270 s (at its longest 327 s); a flight that runs past this is stopped


@dataclass
class FlightLogRecorder:
    """Every tick's commands and telemetry, as the fit wants them."""

    rows: list[tuple[float, ...]] = field(default_factory=list)

    def add(self, t: float, commands: tuple[float, float, float, float], tel: Telemetry | None) -> None:
        def value(x: float | None) -> float:
            return math.nan if x is None else float(x)

        self.rows.append((t, *commands, value(tel and tel.range_m), value(tel and tel.yaw_rate_dps), value(tel and tel.flow_x_rad_s)))

    def record(self) -> FlightRecord:
        a = np.asarray(self.rows, float)
        return FlightRecord(t=a[:, 0], commands=a[:, 1:5], range_m=a[:, 5], yaw_rate_dps=a[:, 6], flow_x_rad_s=a[:, 7])


def hover_guess(config: FlightConfig) -> float:
    """The vertical command the config's model says cancels the buoyancy: where the hold's integral starts."""
    return command_for_thrust(config.net_buoyancy_n / 2.0, config.vertical_thrust_n, config.vertical_reverse_ratio, config.motor_deadband)


def fly(client: MspClient, pilot: CalibrationPilot, clock: Callable[[], float], wait_until: Callable[[float], None],
        period_s: float, should_stop: Callable[[], str | None] = lambda: None, max_s: float = MAX_FLIGHT_S) -> FlightLogRecorder:
    """Poll, decide, command every ``period_s`` until the script is done or stopped; neutral at the end, always."""
    log = FlightLogRecorder()
    start = tick = clock()
    try:
        while not pilot.done:
            reason = should_stop()
            if reason is None and tick - start > max_s:
                reason = "time limit"
            if reason is not None:
                pilot.abort(reason)
                break
            telemetry = client.poll()
            commands = pilot.step(tick, telemetry)
            client.send_motors(to_microseconds(commands))
            log.add(tick, commands, telemetry)
            tick += period_s
            wait_until(tick)
    finally:
        client.send_neutral()
    return log


@dataclass
class SimBoardRun:
    """The simulated board on a manual clock: a flight of minutes takes seconds."""

    board: SimMotorBoard
    clock: ManualClock
    client: MspClient

    def wait_until(self, t: float) -> None:
        self.clock.t = round(t, 9)
        self.board.advance_to(self.clock.t)


def sim_run(params: BoardParams, seed: int = 1, timeout_s: float = 0.03, start_z: float = 1.2) -> SimBoardRun:
    board = SimMotorBoard(board_with(params, z=start_z), seed=seed)
    clock = ManualClock()
    return SimBoardRun(board, clock, MspClient(SimSerial(board, clock), timeout_s=timeout_s, clock=clock))


@dataclass
class Calibration:
    """The outcome: the fitted plant, the config built from it, the flight it came from."""

    fit: PlantFit
    config: FlightConfig
    record: FlightRecord
    pilot: CalibrationPilot
    details: Any  # sysid.AxisFits and Signals, for the plots
    # Why no config may be fitted: values no blimp can have (see :func:`unphysical`), or a flight stopped before its
    # script ended (:func:`calibrate_from`). Then ``config`` is the one flown with, unfitted.
    problems: list[str] = field(default_factory=list)
    stand_scaled: bool = False  # the horizontal values were scaled by a thrust stand's figure, not the heave drag


class NothingFlown(ValueError):
    """The calibration flight ended before its first step: there is nothing to fit."""


def calibrate_from(log: FlightLogRecorder, pilot: CalibrationPilot, config: FlightConfig,
                   stand_thrust_n: Estimate | None = None) -> Calibration:
    """Fit what was flown. A flight stopped before its script ended is fitted for the report, never for a config: its
    axes not yet stepped come out of the fit as anything (a flight stopped 45 s in, before any yaw step, wrote a yaw
    drag 160 times the shipped one and a surge mass 6.6 times the truth, inside boxes of 1.14-1.29, and the blimp
    flown with it spun at six times the commanded turn and never stopped: the session-32 review, finding 1)."""
    if not pilot.segments:
        raise NothingFlown(f"the flight ended before its first step ({pilot.aborted or 'no step flown'}): nothing to fit")
    record = log.record()
    fit, fits, sig = identify(record, config.net_buoyancy_n, config.arm_m, config.altitude_min_m - 0.4, config.altitude_max_m + 0.4,
                              stand_thrust_n)
    fitted = fitted_config(config, fit, braked(pilot))
    problems = unphysical(fitted)
    if pilot.aborted:
        problems.insert(0, f"the flight was stopped before its script ended ({pilot.aborted}), so the steps not flown "
                           f"were fitted from nothing")
    return Calibration(fit, config if problems else fitted, record, pilot, (fits, sig), problems, stand_thrust_n is not None)


# Fitted values that must be positive (a mass, an inertia, a thrust) and the ratios that must lie in [0, 1] (a
# one-direction propeller may give no reverse thrust: corner-MTdL's fit at seed 4 found none and flew every goal).
POSITIVE = ("mass_kg", "heave_mass", "yaw_inertia_kg_m2", "horizontal_thrust_n", "vertical_thrust_n")
RATIOS = ("horizontal_reverse_ratio", "vertical_reverse_ratio")


def unphysical(fitted: FlightConfig) -> list[str]:
    """The fitted values no blimp can have, as ``name = value``: a fit that found them did not identify the plant.

    On the heavy weak corner-MtdL at flight seed 15 the fit found a surge mass of -0.07 kg, a horizontal thrust of
    -0.007 N and a yaw inertia of -0.006, yet boxes of 1.29-1.3: the controller, dividing by them, never stopped the
    blimp (session 25). Such a fit is reported, not flown: the calibration keeps the config it flew with."""
    bad = [name for name in POSITIVE if not (math.isfinite(getattr(fitted, name)) and getattr(fitted, name) > 0.0)]
    bad += [name for name in RATIOS if not 0.0 <= getattr(fitted, name) <= 1.0]  # NaN included
    return [f"{name} = {getattr(fitted, name)}" for name in bad]


def braked(pilot: CalibrationPilot) -> bool:
    """Whether the flight flew a reverse surge step: a brake, whose response the fitted reverse thrust is."""
    return any(pilot.script[index].axis == "surge" and pilot.script[index].level < 0.0 for index, _, _ in pilot.segments)


# The controller's drag models are simpler than the fit's: translational drag is a fixed 0.02 N per m/s plus
# ``quadratic_drag`` v|v| (estimators.air_drag), yaw drag is ``yaw_drag`` r|r| alone. Its quadratic terms are
# set so that its drag equals the fitted one at a typical speed (the commanded cruise and turn rate); this
# also keeps a poorly separated linear/quadratic pair from reaching the controller as two wrong halves.
AIR_LINEAR_DRAG = 0.02
DEADBAND_STANDARD_ERRORS = 2.0  # the deadband the mixer compensates: the fit's, this many standard errors low
SPEED_REFERENCE_M_S = 0.15
YAW_REFERENCE_RAD_S = math.radians(20.0)


def equivalent_quadratic(linear: float, quadratic: float, model_linear: float, at: float) -> float:
    """The quadratic coefficient that, with ``model_linear``, gives the fitted drag at speed ``at``."""
    return (linear * at + quadratic * at * at - model_linear * at) / (at * at)


def fitted_config(config: FlightConfig, fit: PlantFit, braking_shown: bool = False) -> FlightConfig:
    """``config`` with the fitted plant: what the controller reads, and how much it may now trust it;
    ``braking_shown`` when the flight braked (:func:`braked`), so the speed cap may count on the fit."""
    def v(name: str) -> float:
        return float(fit.value(name))

    axes = axis_uncertainties(fit)
    fitted = replace(
        config,
        mass_kg=round(v("surge_mass_kg"), 4),
        heave_mass_kg=round(v("heave_mass_kg"), 4),
        yaw_inertia_kg_m2=round(v("yaw_inertia_kg_m2"), 5),
        yaw_drag=round(max(equivalent_quadratic(v("yaw_linear_drag"), v("yaw_quadratic_drag"), 0.0, YAW_REFERENCE_RAD_S), 0.0), 5),
        quadratic_drag=round(max(equivalent_quadratic(v("linear_drag_n_per_m_s"), v("quadratic_drag"), AIR_LINEAR_DRAG, SPEED_REFERENCE_M_S), 0.0), 4),
        horizontal_thrust_n=round(v("horizontal_thrust_n"), 4),
        vertical_thrust_n=round(v("vertical_thrust_n"), 4),
        horizontal_reverse_ratio=round(min(max(v("horizontal_reverse_ratio"), 0.0), 1.0), 3),
        vertical_reverse_ratio=round(min(max(v("vertical_reverse_ratio"), 0.0), 1.0), 3),
        motor_deadband=round(float(min(max(0.5 * (low_deadband(fit, "horizontal_deadband") + low_deadband(fit, "vertical_deadband")), 0.0), 0.5)), 4),
        motor_lag_s=round(min(max(v("motor_lag_s"), 0.01), 0.5), 4),
        plant_uncertainty=max(axes.values()),
        heave_uncertainty=axes["heave"],
        surge_uncertainty=axes["surge"],
        yaw_uncertainty=axes["yaw"],
        braking_shown=braking_shown,
    )
    return replace(fitted, surge_brake_shown=brake_shown(fit, fitted) if braking_shown else 0.0)


def low_deadband(fit: PlantFit, name: str) -> float:
    """A pair's fitted deadband ``DEADBAND_STANDARD_ERRORS`` standard errors low (not below 0): what the mixer adds to
    every command it compensates.

    A deadband compensated too wide pushes more than asked at every small force, where too narrow pushes less and
    the loops' feedback makes it up. On corner-mtDL at seed 10 the fit found 0.190 +- 0.069 (horizontal) and
    0.258 +- 0.027 (vertical) against the plant's 0.12, with a motor lag of 0.056 against 0.15 (the two trade off
    on a weak, draggy plant): the first forward peaked at 1.24 of the command (docs/calibrate-flight.md, session 25)."""
    estimate = fit.values[name]
    return max(0.0, float(estimate.value) - DEADBAND_STANDARD_ERRORS * float(estimate.stderr))


def brake_shown(fit: PlantFit, config: FlightConfig) -> float:
    """The reverse thrust per surge mass the flight's reverse steps measured, at 3 standard errors low, as a share of
    what ``config`` models (its reverse thrust over its surge mass), rounded down: what the speed cap may count on.

    3 standard errors low as the fit's boxes count them (:func:`axis_uncertainties`): the value divided by
    ``1 + 3 x`` its relative error. The surge fit measures it directly (its ``reverse_thrust_per_mass`` column,
    what a brake decelerates by), where the config's model multiplies the thrust per mass by the reverse ratio
    averaged with the yaw fit's: on the heavy weak corners (seeds 1-2) the direct value was within -4..+11 % of
    the truth, the model's within -25..+7 % (docs/calibrate-flight.md, session 20).
    """
    measured = fit.values["surge_reverse_thrust_per_mass"]
    modelled = config.horizontal_thrust_n * config.horizontal_reverse_ratio / config.mass_kg
    low = measured.value / (1.0 + 3.0 * measured.relative)
    if not (modelled > 0.0 and math.isfinite(low) and low > 0.0):
        return 0.0
    return min(math.floor(1000.0 * low / modelled) / 1000.0, 4.0)  # the key's range


# How far the fitted model may still be off, per axis, in the units the loops' learning box uses
# (``estimators.effectiveness_bounds``: an axis' acceleration per modelled push lies within U^-2..U^2, a reverse
# push's (surge) down to U^-3). The loops divide by each axis' thrust-to-inertia ratio (the surge mass, thrust and
# yaw inertia scale together with one poorly determined factor and the loops see only their ratios) and by the
# reverse ratios; the heave mass turns the weighed buoyancy into the hover push. Each may be off by 3 standard
# errors (a factor 1 + 3 x its relative error), and U is the smallest box that holds that. One number for all
# axes (the worst ratio's 1 + 3 x error, as before) let the loosest fit, usually the vertical reverse ratio from
# short reverse steps, keep the surge's learned speed cap: cruise at 0.4-0.8 of the commanded speed.
MAX_UNCERTAINTY, UNKNOWN_UNCERTAINTY = 4.0, 2.0
# The heave box is never wider than the learning box a config without a fit flies (``UNKNOWN_UNCERTAINTY``, the
# shipped ``plant_uncertainty``). The heave effectiveness starts at the box's strongest, U^2, and a fit whose vertical
# reverse ratio was loose (short reverse steps on a heavy corner that hovers on its motors' forward thrust, where
# that ratio plays no part) set U at 3.7-4: the altitude loop pushed a 13th-16th of what it should, no window ever
# changed the modelled climb rate enough to teach it, and the body sank to the floor (calibrated corner-MtdL, flight
# seeds 1 and 5: hold RMS 0.63 m, safety flight 0.40 m outside the limits; docs/calibrate-flight.md, session 22).
MAX_HEAVE_UNCERTAINTY = UNKNOWN_UNCERTAINTY


def axis_uncertainties(fit: PlantFit) -> dict[str, float]:
    """Per axis (heave, surge, yaw), the smallest ``plant_uncertainty`` whose box holds the fit's 3-sigma errors."""
    def factor(name: str) -> float:
        return 1.0 + 3.0 * fit.values[name].relative

    def box(forward: float, reverse: float, reverse_power: float, cap: float = MAX_UNCERTAINTY) -> float:
        u = max(math.sqrt(forward), (forward * reverse) ** (1.0 / reverse_power))
        return min(cap, math.ceil(100.0 * u) / 100.0) if math.isfinite(u) else UNKNOWN_UNCERTAINTY

    horizontal_reverse = factor("horizontal_reverse_ratio")
    heave = max(factor("heave_thrust_per_mass"), factor("heave_mass_kg"))
    return {"heave": box(heave, factor("vertical_reverse_ratio"), 2.0, MAX_HEAVE_UNCERTAINTY),  # U^+-2 both ways
            "surge": box(factor("surge_thrust_per_mass"), horizontal_reverse, 3.0),
            "yaw": box(factor("yaw_torque_per_inertia"), horizontal_reverse, 3.0)}


# The config keys the fit sets directly, and the fitted value each one is (for the uncertainty comment);
# the others are derived, and say from what.
CONFIG_SOURCES = {"mass_kg": "surge_mass_kg", "heave_mass_kg": "heave_mass_kg", "yaw_inertia_kg_m2": "yaw_inertia_kg_m2",
                  "horizontal_thrust_n": "horizontal_thrust_n", "vertical_thrust_n": "vertical_thrust_n",
                  "horizontal_reverse_ratio": "horizontal_reverse_ratio", "vertical_reverse_ratio": "vertical_reverse_ratio",
                  "motor_lag_s": "motor_lag_s"}
DERIVED_NOTES = {"quadratic_drag": "the fitted drag at 0.15 m/s as this model's quadratic term (fitted terms above)",
                 "yaw_drag": "the fitted yaw drag at 20 deg/s as a quadratic term (fitted terms above)",
                 "motor_deadband": "mean of the two pairs' fitted deadbands (above), each 2 standard errors low",
                 "plant_uncertainty": "the worst axis below",
                 "heave_uncertainty": "the box holding 3 sigma of the heave thrust per mass, heave mass and vertical reverse ratio",
                 "surge_uncertainty": "the box holding 3 sigma of the surge thrust per mass and horizontal reverse ratio",
                 "yaw_uncertainty": "the box holding 3 sigma of the yaw torque per inertia and horizontal reverse ratio",
                 "net_buoyancy_n": "weighed, not fitted: the fit's scale",
                 "braking_shown": "the flight flew reverse surge steps: the speed cap counts on the fitted reverse thrust",
                 "surge_brake_shown": "the surge fit's reverse thrust per mass, 3 sigma low (/ (1 + 3 x relative error)), over the model's"}


def render_calibrated(full_config: Any, calibration: Calibration) -> str:
    """The whole config as TOML, ``[flight]`` fitted, each fitted key annotated with its standard error, and a
    header with every fitted value (the linear drags the controller does not read) and the residuals.

    Annotations are TOML comments: the settings loader rejects unknown keys, so they cannot be a table.
    """
    from feelium.daemon.config import render_config

    text = render_config(replace(full_config, flight=calibration.config))
    fit = calibration.fit
    lines, section = [], ""
    for line in text.splitlines():
        if line.startswith("["):
            section = line.strip()
        key = line.split(" = ")[0] if " = " in line and not line.startswith("#") else ""
        if section == "[flight]" and key in CONFIG_SOURCES:
            e = fit.values[CONFIG_SOURCES[key]]
            line += f"  # fitted: +- {e.stderr:.3g} (1 sigma, {100 * e.relative:.1f} %)"
        elif section == "[flight]" and key in DERIVED_NOTES:
            line += f"  # {DERIVED_NOTES[key]}"
        lines.append(line)
    header = ["# Fitted by `feelium calibrate flight` (docs/calibrate-flight.md). Value +- standard error:"]
    header += [f"#   {name} = {e.value:.5g} +- {e.stderr:.3g}" for name, e in fit.values.items()]
    header.append("#   horizontal scale: " + ("the thrust stand's horizontal_thrust_n" if calibration.stand_scaled
                                               else "the heave drag (no thrust stand figure given)"))
    header += [f"#   residual {axis}: rms {r['residual_rms']:.4g}, {100 * r['relative_residual']:.0f} % of the measured rate change,"
               f" {int(r['samples'])} samples" for axis, r in fit.residuals.items()]
    return "\n".join(header) + "\n" + "\n".join(lines) + "\n"


def summary(calibration: Calibration) -> dict[str, Any]:
    """The JSON report: every fitted value with its error, the residuals, the flight."""
    fit = calibration.fit
    return {"values": {k: {"value": e.value, "stderr": e.stderr} for k, e in fit.values.items()},
            "residuals": fit.residuals, "plant_uncertainty": calibration.config.plant_uncertainty,
            "axis_uncertainty": {axis: calibration.config.uncertainty(axis) for axis in ("heave", "surge", "yaw")},
            "flight_s": float(calibration.record.t[-1] - calibration.record.t[0]), "steps_flown": len(calibration.pilot.segments),
            "aborted": calibration.pilot.aborted, "problems": calibration.problems,
            "horizontal_scale": "thrust stand" if calibration.stand_scaled else "heave drag"}


def plot_steps(calibration: Calibration, out_dir: Path) -> list[Path]:
    """Per axis, the measured rate against the fitted model's free-run prediction over each step and its settle."""
    from feelium.flight.sysid import predict_rates
    from feelium.lab.plot import Series, line_plot

    fits, sig = calibration.details
    units = {"heave": ("climb rate", "m/s", 1.0), "surge": ("forward speed", "m/s", 1.0), "yaw": ("yaw rate", "deg/s", math.degrees(1.0))}
    t0, paths = float(calibration.record.t[0]), []
    for axis, (name, unit, scale) in units.items():
        series: list[Series] = []
        for index, start_t, end_t in calibration.pilot.segments:
            if calibration.pilot.script[index].axis != axis:
                continue
            start = int(round((start_t - t0) / sig.dt))
            stop = min(int(round((end_t - t0 + 2.0) / sig.dt)), sig.rate[axis].size)
            t = sig.dt * np.arange(stop - start)
            first = not series
            series.append(Series(t, sig.rate[axis][start:stop] * scale, "measured" if first else "", (180, 119, 31)))
            series.append(Series(t, predict_rates(sig, fits, axis, start, stop) * scale, "predicted" if first else "", (14, 127, 255)))
        if series:
            paths.append(line_plot(out_dir / f"calibrate-{axis}.png", series, title=f"{axis}: measured and predicted {name} per step",
                                   xlabel="s since the step began", ylabel=f"{name} ({unit})"))
    return paths


def calibrate_sim(config: FlightConfig, blimp: Any = None, seed: int = 1, drafts: bool = True,
                  sensors: SensorParams | None = None, stand_thrust_n: Estimate | None = None) -> Calibration:
    """Calibrate on the simulated board flying ``blimp`` (default the paper's), in mild drafts.

    The net buoyancy is weighed on a real blimp, so the simulated one's true value stands in for the scale.
    """
    from feelium.flight.blimp_model import BlimpParams
    from feelium.lab.flight.plants import MILD_DRAFTS

    blimp = blimp or BlimpParams()
    config = replace(config, net_buoyancy_n=round(blimp.net_buoyancy_n, 4))
    run = sim_run(BoardParams(blimp=blimp, drafts=MILD_DRAFTS if drafts else None, sensors=sensors or SensorParams()), seed=seed)
    pilot = CalibrationPilot(hover_command=hover_guess(config))
    log = fly(run.client, pilot, run.clock, run.wait_until, 1.0 / config.rate_hz)
    return calibrate_from(log, pilot, config, stand_thrust_n)


def true_values(blimp: Any) -> dict[str, float]:
    """What the fit should find on a simulated ``blimp``, in ``PlantFit`` names.

    The simulator's motor lag is an Euler step of ``PHYSICS_DT`` that applies the updated thrust over the
    whole step: it acts as a continuous lag ``PHYSICS_DT`` shorter than its parameter (the delay of its step
    response's integral), and that is what a fit of the continuous model can find.
    """
    from feelium.flight.sim_board import PHYSICS_DT

    mass = blimp.inertial_mass_kg
    return {"heave_mass_kg": mass * blimp.heave_mass_factor, "surge_mass_kg": mass * blimp.surge_mass_factor,
            "vertical_thrust_n": blimp.vertical_motor.max_thrust_n, "horizontal_thrust_n": blimp.horizontal_motor.max_thrust_n,
            "vertical_reverse_ratio": blimp.vertical_motor.reverse_ratio, "horizontal_reverse_ratio": blimp.horizontal_motor.reverse_ratio,
            "linear_drag_n_per_m_s": blimp.linear_drag_n_per_m_s, "quadratic_drag": blimp.quadratic_drag,
            "yaw_inertia_kg_m2": blimp.yaw_inertia_kg_m2, "yaw_linear_drag": blimp.yaw_linear_drag,
            "yaw_quadratic_drag": blimp.yaw_quadratic_drag, "motor_lag_s": blimp.horizontal_motor.time_constant_s - PHYSICS_DT,
            "vertical_deadband": blimp.vertical_motor.deadband, "horizontal_deadband": blimp.horizontal_motor.deadband}


def recovery_errors(fit: PlantFit, blimp: Any) -> dict[str, float]:
    """Per parameter, the fit's relative error against the simulated truth (absolute for a zero deadband)."""
    return {name: float((fit.value(name) - truth) / truth if truth else fit.value(name)) for name, truth in true_values(blimp).items()}


def calibrate_board(config: FlightConfig, port: str, stand_thrust_n: Estimate | None = None) -> Calibration:
    """Calibrate a real board in real time; ``stop`` on stdin, Ctrl-C or SIGTERM end it with the motors neutral."""
    import signal
    import sys
    import threading
    import time

    from feelium.flight.transport import open_serial

    stop: list[str] = []

    def on_signal(signum: int, _frame: Any) -> None:
        stop.append(signal.Signals(signum).name)

    def read_stdin() -> None:
        for line in sys.stdin:
            if line.strip().lower() == "stop":
                stop.append("stop")
                return

    link: ByteLink = open_serial(port, config.baudrate, config.reply_timeout_s)  # a port that will not open: nothing flew
    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    threading.Thread(target=read_stdin, daemon=True, name="calibrate-stop").start()
    try:
        client = MspClient(link, timeout_s=config.reply_timeout_s)
        pilot = CalibrationPilot(hover_command=hover_guess(config))
        log = fly(client, pilot, time.monotonic, lambda t: time.sleep(max(0.0, t - time.monotonic())), 1.0 / config.rate_hz,
                  should_stop=lambda: stop[0] if stop else None)
    finally:
        link.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return calibrate_from(log, pilot, config, stand_thrust_n)


def tight_goals(config: FlightConfig, blimp: Any, seed: int = 1) -> dict[str, float]:
    """The nominal controller's tight figures flown with ``config`` on ``blimp``: hold in still air (altitude
    and heading RMS) and the cruise speed of a held ``forward`` as a fraction of the commanded one and of its
    target, the commanded speed or, if lower, the fastest ``blimp`` can stop from within the stop goal
    (``stoppable.cruise_target``: the cruise goal as decided in docs/calibrate-flight.md)."""
    from feelium.lab.flight import scenarios as sc
    from feelium.lab.flight.stoppable import cruise_target

    held = sc.hold(config, drafts=False, seed=seed, seconds=15.0, blimp=blimp)
    forward = sc.motion(config, "forward", hold_s=5.0, seed=seed, blimp=blimp)
    cruising = (forward.t >= forward.expired_s - 0.5 - 2.0) & (forward.t <= forward.expired_s - 0.5)
    cruise = float(np.mean(forward.fraction[cruising]))
    target = cruise_target(forward.commanded, blimp, config.max_output)
    return {"altitude_rms_m": held.altitude_rms_m, "heading_rms_deg": held.heading_rms_deg,
            "cruise_fraction": cruise, "forward_latency_s": forward.latency_s, "v_stop_m_s": target["v_stop_m_s"],
            "cruise_target_m_s": target["cruise_target_m_s"],
            "cruise_fraction_of_target": cruise * target["commanded_m_s"] / target["cruise_target_m_s"]}
