"""``feelium record``: the live rear camera to a recording in format v1."""

from __future__ import annotations

import argparse

from feelium.cli import CommandRegistry


def register(registry: CommandRegistry) -> None:
    rec = registry.command(
        "record",
        "Record the live rear camera (format v1) to collect real data on the blimp. SIGTERM, SIGINT (Ctrl-C) or "
        "SIGHUP end the take early and keep it (exit 0); a nearly full disk keeps a shorter take and exits 1.",
        _record,
    )
    rec.add_argument("--out", required=True, help="recording directory to create (must not exist)")
    rec.add_argument("--seconds", type=float, default=None, help="stop after this much camera time (default: until stopped)")
    rec.add_argument("--config", help="TOML config file ([rear_camera] chooses the camera)")
    rec.add_argument("--sim", action="store_true", help="record the scene simulator instead of the camera")
    rec.add_argument("--name", help="recording name (default: rec-<date>-<time>)")
    rec.add_argument("--session", default="", help="free text grouping recordings taken under the same conditions")


def _record(args: argparse.Namespace) -> int:
    import dataclasses
    import logging
    import sys
    import threading
    import time
    from pathlib import Path

    from feelium.cameras.base import CameraUnavailable
    from feelium.cameras.record import default_name, record, stop_on_signals
    from feelium.daemon.assembly import rear_camera
    from feelium.daemon.backends import for_this_machine
    from feelium.daemon.config import load_config
    from feelium.daemon.journal import setup_logging

    setup_logging(logging.INFO)
    config = load_config(args.config)
    if args.sim:
        config = dataclasses.replace(config, rear_camera=dataclasses.replace(config.rear_camera, backend="sim"))
    config = for_this_machine(config)
    if args.seconds is not None and not args.seconds > 0:
        print("feelium record: --seconds must be positive", file=sys.stderr)
        return 2
    out = Path(args.out)
    if out.exists():
        print(f"feelium record: {out} already exists", file=sys.stderr)
        return 1
    try:
        source = rear_camera(config, time.monotonic)
        if source is None:
            print("feelium record: the rear camera is off in the config ([rear_camera] backend)", file=sys.stderr)
            return 1
        camera = source.open()
    except CameraUnavailable as exc:
        print(f"feelium record: {exc}", file=sys.stderr)
        return 1
    if source.backend == "sim":
        print("feelium record: recording the scene simulator (--sim, or `auto` off a Raspberry Pi)", file=sys.stderr)
    name = args.name or default_name(time.time())
    shown = {"at": 0.0}

    def progress(frames: int, t: float) -> None:
        if t - shown["at"] >= 5.0:
            shown["at"] = t
            print(f"{frames} frames, {t:.1f} s", file=sys.stderr)

    stop = threading.Event()
    try:
        with stop_on_signals(stop) as caught:
            take = record(
                camera,
                out,
                seconds=args.seconds,
                fps=config.rear_camera.fps,
                name=name,
                session=args.session,
                source="device" if source.backend == "picamera2" else "synthetic",
                extra_meta={"recorder": {"backend": source.backend, "config": dataclasses.asdict(config.rear_camera)}},
                stop=stop,
                on_frame=progress,
            )
    except OSError as exc:  # the writer removed its temp dir: nothing half is left
        print(f"feelium record: cannot write {out}: {exc.strerror or exc}; nothing kept", file=sys.stderr)
        return 1
    finally:
        camera.close()
    summary = f"{take.path} ({take.frames} frames, {take.seconds:.1f} s)"
    if take.ended == "disk full":
        print(f"feelium record: {take.problem} in {out.parent}: kept a shorter take {summary}", file=sys.stderr)
        return 1
    print(f"recorded {summary}" + (f"; stopped by {caught[0]}" if caught else ""))
    return 0
