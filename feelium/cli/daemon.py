"""``feelium run``, ``feelium bench daemon``, ``feelium bench board``, ``feelium bench quota`` and ``feelium bench soak``."""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
from pathlib import Path
from typing import Any

from feelium.cli import CommandRegistry


def register(registry: CommandRegistry) -> None:
    run = registry.command("run", "Run the blimp: every service, supervised (simulated when there is no hardware).", _run)
    run.add_argument("--config", help="TOML config file (default: built-in defaults)")
    source = run.add_mutually_exclusive_group()
    source.add_argument("--sim", action="store_true", help="run every part on its simulator, whatever the hardware")
    source.add_argument(
        "--replay", metavar="PATH",
        help="rear camera replays this recording or dataset, with its projector stream when it has one (touch predicts "
        "the light from the recorded frames and the map beside them, as replay and eval do); the rest simulated",
    )  # fmt: skip
    run.add_argument(
        "--projector-calibration", metavar="FILE",
        help="with --replay: the projector map of the replayed streams (default: projector-calibration.npz beside them)",
    )
    run.add_argument("-v", "--verbose", action="count", default=0, help="debug logging (overrides [daemon] log_level)")

    bench = registry.subcommand(
        "bench", "daemon", "Run the daemon in sim mode and measure memory, CPU per frame and dropped frames.", _bench
    )
    bench.add_argument("--seconds", type=float, default=60.0, help="how long the daemon runs (default 60)")
    bench.add_argument("--config", help="TOML config file (the sim backends are forced)")
    bench.add_argument("--json", metavar="FILE", help="also write the results as JSON here")
    bench.add_argument(
        "--per-service-seconds",
        type=float,
        default=10.0,
        help="then run each service alone this long in a fresh process, for its memory (0 = skip; default 10)",
    )
    board = registry.subcommand(
        "bench", "board", "The daemon on its real data path at real rates, projected onto a Pi Zero 2 W (docs/performance.md).",
        _bench_board,
    )
    board.add_argument("--minutes", type=float, default=5.0, help="measured window after a 3 s warm-up (default 5)")
    board.add_argument("--config", help="TOML config file (sim backends forced; cameras preloaded; board out of process)")
    board.add_argument("--front-fps", type=float, help="front camera and MJPEG rate (default: [front_camera] fps)")
    board.add_argument("--json", metavar="FILE", help="also write the results as JSON here")
    board.add_argument("--cgroup", metavar="DIR", help="join this existing cgroup (a CPU quota) for the measured window")
    board.add_argument(
        "--motion-transport", choices=("websocket", "http"), default="websocket",
        help="how the headset sends its 20 Hz motion: messages on the events WebSocket (default) or POST /motion",
    )
    board.add_argument(
        "--numeric-split-seconds", type=float, default=20.0,
        help="then profile the daemon this long for each service's numpy/OpenCV share, projected at 6x (the rest at "
        "10x); 0 = everything at 10x (default 20)",
    )
    board.add_argument(
        "--numeric-split-by", choices=("auto", "perf", "hook"), default="auto",
        help="how the share is measured: perf samples the process (needs Linux perf), hook times numpy's and "
        "OpenCV's calls (a lower bound); auto = perf where usable (default)",
    )
    board.add_argument(
        "--projected-light", choices=("on", "off"), default="on",
        help="touch compensates the projector's light with a simulated calibration, as on the blimp (default on)",
    )
    board.add_argument(
        "--event-loop", choices=("auto", "uvloop", "asyncio"),
        help="the daemon's event loop (default: [daemon] event_loop); asyncio's lets the bench charge each loop "
        "callback to its service",
    )
    quota = registry.subcommand(
        "bench", "quota",
        "The board bench inside a CPU quota equal to the projected budget, the quota derived on this host just before "
        "(issue 16, point 3; docs/performance.md). Needs root for the cgroup.",
        _bench_quota,
    )
    quota.add_argument("--cgroup", required=True, metavar="DIR",
                       help="a cgroup with the cpu controller, created if absent (v1: /sys/fs/cgroup/cpu/NAME, v2: /sys/fs/cgroup/NAME)")
    quota.add_argument("--minutes", type=float, default=2.0, help="measured window inside the quota (default 2)")
    quota.add_argument("--calibrate-minutes", type=float, default=1.0,
                       help="the unconfined run the quota is derived from (default 1)")
    quota.add_argument("--numeric-split-seconds", type=float, default=20.0,
                       help="the unconfined run's numeric split, for the factor (default 20; 0 = everything at 10x)")
    quota.add_argument("--quota-us", type=int, help="use this quota instead of deriving it (no unconfined run)")
    quota.add_argument("--period-us", type=int, default=10_000, help="the quota's period (default 10000)")
    quota.add_argument("--config", help="TOML config file (sim backends forced; cameras preloaded; board out of process)")
    quota.add_argument("--json", metavar="FILE", help="also write both runs, the quota and the verdict as JSON here")
    soak = registry.subcommand(
        "bench", "soak", "The board bench run long (30 min): RSS, growth after warm-up, rates held (docs/daemon.md).",
        _bench_soak,
    )
    soak.add_argument("--minutes", type=float, default=30.0, help="measured window after a 3 s warm-up (default 30)")
    soak.add_argument("--config", help="TOML config file (sim backends forced; cameras preloaded; board out of process)")
    soak.add_argument("--json", metavar="FILE", help="also write the results and the verdict as JSON here")


def _run(args: argparse.Namespace) -> int:
    from feelium.daemon.config import load_config
    from feelium.daemon.journal import effective_level, setup_logging
    from feelium.daemon.runner import run_process, with_overrides

    if args.projector_calibration and not args.replay:
        print("feelium run: --projector-calibration goes with --replay", file=sys.stderr)
        return 2
    config = with_overrides(
        load_config(args.config), sim=args.sim, replay=args.replay, projector_calibration=args.projector_calibration
    )
    setup_logging(effective_level(config.daemon.log_level, args.verbose))
    with contextlib.ExitStack() as scratch:
        # Only a replay that fits its map needs a folder for it: every other run made an empty one, left behind in
        # /tmp whenever the process ended by os._exit (a stuck device thread) or a kill.
        if args.replay and not args.projector_calibration and config.rear_camera.projection_compensation != "off":
            folder = Path(scratch.enter_context(tempfile.TemporaryDirectory(prefix="feelium-replay-map-")))
            try:
                config = _with_fitted_replay_map(config, Path(args.replay), folder)
            except (ValueError, OSError) as exc:
                print(f"feelium run: --replay: {exc}", file=sys.stderr)
                return 1
        return run_process(config)


def _with_fitted_replay_map(config: Any, root: Path, scratch: Path) -> Any:
    """``config`` replaying with the map fitted from the calibration recording beside the replayed streams, when
    that is what they find (the daemon loads saved maps only: fitting is lab code, which this command may load)."""
    import dataclasses
    import logging

    from feelium.lab.touch.recorded_light import replay_map
    from feelium.recording import RecordingError

    try:
        saved = replay_map(root, config.projector, config.touch, scratch)
    except RecordingError as exc:  # a bad recording: the replay camera skips it and says so
        logging.getLogger(__name__).warning("replay: %s", exc)
        return config
    if saved is None:
        return config
    logging.getLogger(__name__).info("replay: the projector map fitted from the calibration recording beside the streams")
    rear = dataclasses.replace(config.rear_camera, replay_projector_calibration=str(saved))
    return dataclasses.replace(config, rear_camera=rear)


def _bench(args: argparse.Namespace) -> int:
    from feelium.lab.daemon.bench import bench_daemon_command

    return bench_daemon_command(args)


def _bench_board(args: argparse.Namespace) -> int:
    from feelium.lab.daemon.board import bench_board_command

    return bench_board_command(args)


def _bench_quota(args: argparse.Namespace) -> int:
    from feelium.lab.daemon.budgetquota import bench_quota_command

    return bench_quota_command(args)


def _bench_soak(args: argparse.Namespace) -> int:
    from feelium.lab.daemon.soak import bench_soak_command

    return bench_soak_command(args)
