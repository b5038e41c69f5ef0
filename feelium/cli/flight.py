"""``feelium flight probe``, ``feelium calibrate flight`` and ``feelium bench flight``."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

from feelium.cli import CommandRegistry

if TYPE_CHECKING:
    from feelium.flight.sysid import Estimate


OUT_DEFAULT = "bench-out/flight"


def register(registry: CommandRegistry) -> None:
    flight = registry.group("flight", "The motor board and the flight controller.")
    probe = flight.add_parser(
        "probe",
        help="Ask a motor board what it reports (API version, attitude, altitude, rangefinder, battery, motors) as JSON.",
        description="Connect to a motor board over MSP and print what it reports as JSON; exit 1 when nothing answers.",
    )
    target = probe.add_mutually_exclusive_group(required=True)
    target.add_argument("--port", help="serial device or pyserial URL, e.g. /dev/ttyUSB0 or socket://127.0.0.1:5761")
    target.add_argument("--sim", action="store_true", help="probe the simulated motor board instead")
    probe.add_argument("--baud", type=int, default=115200, help="serial speed (default 115200)")
    probe.add_argument("--timeout", type=float, default=0.5, help="seconds to wait for each reply (default 0.5)")
    probe.set_defaults(handler=_probe)
    calibrate = registry.subcommand(
        "calibrate", "flight", "Fly a short scripted flight (about 4-5 min) and fit this blimp's plant; type stop or Ctrl-C to abort.", _calibrate
    )
    where = calibrate.add_mutually_exclusive_group(required=True)
    where.add_argument("--port", help="the motor board's serial device or pyserial URL")
    where.add_argument("--sim", action="store_true", help="the simulated board (fast, simulated time)")
    calibrate.add_argument("--config", help="TOML config file: its [flight] net_buoyancy_n (weighed) and arm_m give the scale")
    calibrate.add_argument("--out", default="bench-out/calibrate-flight", help="directory for the fitted config, JSON and plots")
    calibrate.add_argument("--plant", type=int, help="with --sim: fly randomised plant N of the plant set (0-15 are the box's corners)")
    calibrate.add_argument("--seed", type=int, help="with --sim: simulation seed (default 1)")
    calibrate.add_argument("--stand-thrust-n", type=float,
                           help="one horizontal motor's full forward thrust read on a thrust stand, newtons (docs/motor-board.md's "
                                "acceptance test): scales the surge mass, drags and yaw inertia directly instead of through the heave drag")
    calibrate.add_argument("--stand-error", type=float,
                           help="with --stand-thrust-n: its relative standard error (default 0.05: 1.3 g of a 25 g reading)")
    bench = registry.subcommand("bench", "flight", "Fly the simulator: hold, climb, commands, quietness against an untuned PID.", _bench)
    bench.add_argument("--out", help=f"directory for the JSON and PNG plots (default {OUT_DEFAULT}; not with --plants)")
    bench.add_argument("--seed", type=int, default=1, help="simulation seed (with --plants: of every flight and calibration)")
    bench.add_argument("--config", help="TOML config file (its [flight] section is used)")
    bench.add_argument("--plants", type=int, help="instead: the safety goals across N randomised plants (corners first), median and worst")
    bench.add_argument("--json", help="with --plants: write the report here (default: print it)")
    bench.add_argument("--workers", type=int, help="with --plants: processes flying plants in parallel (default 1)")
    bench.add_argument("--no-flow", action="store_true", help="with --plants: a board without the optical-flow sensor")
    bench.add_argument("--calibrated", action="store_true",
                       help="with --plants: also calibrate each plant (calibrate flight) and fly it with the fitted config: before and after")
    bench.add_argument("--only", help="with --plants: these indices of the set alone, e.g. 8-11 (the heavy weak corners) or 0,3,8")
    bench.add_argument("--command-delay-ms", type=float,
                       help="with --plants: the simulated board's motors act this long after a command arrives (a phase sweep: 0, 2.5, 5, 7.5)")


def _probe(args: argparse.Namespace) -> int:
    from feelium.flight.probe import ProbeError, probe_board

    try:
        report = probe_board(port=args.port, sim=args.sim, baudrate=args.baud, timeout_s=args.timeout)
    except ProbeError as exc:
        print(f"feelium flight probe: {exc}", file=sys.stderr)
        return 1
    print(json.dumps(report, indent=2))
    return 0


def _calibrate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from feelium.daemon.config import load_config
    from feelium.lab.flight.calibrate import NothingFlown, calibrate_board, calibrate_sim, render_calibrated, summary

    full = load_config(args.config)
    stand = _stand_thrust(args)
    if not args.sim and (args.plant is not None or args.seed is not None):
        raise SystemExit("calibrate flight: --plant and --seed pick a simulated plant and its air; they need --sim")
    seed = 1 if args.seed is None else args.seed
    if args.plant is not None and args.plant < 0 or seed < 0:
        raise SystemExit("calibrate flight: --plant and --seed must be 0 or more")
    out = Path(args.out)
    try:  # before anything flies: a bad --out found after four minutes of flight loses the flight
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".feelium-write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise SystemExit(f"calibrate flight: cannot write to --out {out}: {exc}") from None
    try:
        if args.sim:
            from feelium.lab.flight.plants import plant_set

            blimp = None if args.plant is None else plant_set(args.plant + 1)[args.plant].blimp
            calibration = calibrate_sim(full.flight, blimp, seed=seed, stand_thrust_n=stand)
        else:
            calibration = calibrate_board(full.flight, args.port, stand_thrust_n=stand)
    except NothingFlown as exc:
        print(f"calibrate flight: {exc}; the motors are neutral and no file was written.", file=sys.stderr)
        return 1
    except OSError as exc:  # the port would not open, or the link died in flight (the board's watchdog stops the motors)
        if args.sim:
            raise
        print(f"calibrate flight: the link to {args.port} failed: {exc}; no file was written.", file=sys.stderr)
        return 1
    from feelium.lab.flight.calibrate import plot_steps
    from feelium.lab.report import finite_or_null

    if not calibration.problems:
        (out / "flight-calibrated.toml").write_text(render_calibrated(full, calibration), encoding="utf-8")
    report = summary(calibration)
    report["plots"] = [str(p) for p in plot_steps(calibration, out)]
    text = json.dumps(finite_or_null(report), indent=1, allow_nan=False)
    (out / "calibration.json").write_text(text + "\n", encoding="utf-8")
    print(text)
    if calibration.problems:
        advice = ("Fly the whole script to fit a config." if calibration.pilot.aborted
                  else "Fly it again in calmer air, or keep the config you have.")
        print(f"calibrate flight: no config written ({'; '.join(calibration.problems)}); the report and plots are in "
              f"{out}. {advice}", file=sys.stderr)
        return 1
    print(f"fitted config: {out / 'flight-calibrated.toml'} (use it with --config, or copy its [flight] section)")
    return 0


def _stand_thrust(args: argparse.Namespace) -> Estimate | None:
    """The thrust stand's figure as an estimate, or None. A figure the config could not hold (a reading in grams: 25
    for 0.25 N) or an error without a figure is refused before anything flies, not after four minutes of flight."""
    from dataclasses import fields

    from feelium.flight.config import FlightConfig
    from feelium.flight.sysid import Estimate

    if args.stand_thrust_n is None:
        if args.stand_error is not None:
            raise SystemExit("calibrate flight: --stand-error needs --stand-thrust-n (the figure it is the error of)")
        return None
    bounds = next(f.metadata for f in fields(FlightConfig) if f.name == "horizontal_thrust_n")
    if not (math.isfinite(args.stand_thrust_n) and bounds["min"] <= args.stand_thrust_n <= bounds["max"]):
        raise SystemExit(f"calibrate flight: --stand-thrust-n must be one motor's thrust in newtons, {bounds['min']}-"
                         f"{bounds['max']} as [flight] horizontal_thrust_n allows, got {args.stand_thrust_n}")
    error = 0.05 if args.stand_error is None else args.stand_error
    if not (math.isfinite(error) and 0.0 < error < 1.0):
        raise SystemExit(f"calibrate flight: --stand-error must be a relative error between 0 and 1, got {error}")
    return Estimate(args.stand_thrust_n, args.stand_thrust_n * error)


def _indices(text: str | None, count: int) -> list[int] | None:
    """``8-11`` or ``0,3,8-11``: plant indices of a set of ``count``, in order; a malformed or out-of-set one is refused."""
    if text is None:
        return None
    out: list[int] = []
    for part in text.split(","):
        first, _, last = part.partition("-")
        try:
            start, stop = int(first), int(last or first)
        except ValueError:
            raise SystemExit(f"bench flight: --only takes plant indices like 8-11 or 0,3,8, got {text!r}") from None
        if stop < start:
            raise SystemExit(f"bench flight: --only {part!r} runs backwards: write the lower index first")
        out += range(start, stop + 1)
    if not out or any(not 0 <= index < count for index in out):
        raise SystemExit(f"bench flight: --only {text!r} names plants outside the set of --plants {count} (0-{count - 1})")
    return out


def _bench(args: argparse.Namespace) -> int:
    from pathlib import Path

    from feelium.daemon.config import load_config
    from feelium.lab.flight.bench import format_table, run_bench

    config = load_config(args.config).flight
    given = [name for name in ("json", "only", "workers", "command_delay_ms") if getattr(args, name) is not None]
    given += [name for name in ("calibrated", "no_flow") if getattr(args, name)]  # flags: False when not given
    if args.plants is None and given:
        raise SystemExit(f"bench flight: --{given[0].replace('_', '-')} needs --plants N")
    if args.plants is not None and args.plants < 1:
        raise SystemExit(f"bench flight: --plants must be 1 or more, got {args.plants}")
    if args.workers is not None and args.workers < 1:
        raise SystemExit(f"bench flight: --workers must be 1 or more, got {args.workers}")
    if args.plants is not None and args.out is not None:
        raise SystemExit("bench flight: --out is the nominal bench's; with --plants the report goes to --json")
    if args.plants:
        from feelium.lab.flight.plant_bench import format_plant_table, run_plant_bench
        from feelium.lab.report import emit_report

        report = run_plant_bench(config, args.plants, workers=1 if args.workers is None else args.workers, flow=not args.no_flow, calibrated=args.calibrated,
                                 command_delay_s=(args.command_delay_ms or 0.0) / 1000.0, only=_indices(args.only, args.plants), flight_seed=args.seed)
        emit_report(format_plant_table(report), report, args.json)
        return 0
    out = args.out or OUT_DEFAULT
    results = run_bench(config, Path(out), seed=args.seed)
    print(format_table(results))
    print(f"JSON and plots in {out}/")
    return 0
