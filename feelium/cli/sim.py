"""``feelium simulate ...``: synthetic, labelled recordings from the scene simulator."""

from __future__ import annotations

import argparse
import os
import sys
import time

from feelium.cli import CommandRegistry


def register(registry: CommandRegistry) -> None:
    parser = registry.subcommand(
        "simulate",
        "paper-protocol",
        "Write the paper's evaluation protocol (228 trials, 3 sessions, 3 continuous clips) as a labelled dataset.",
        _paper_protocol,
    )
    parser.add_argument("--out", required=True, help="dataset directory to write (created if missing)")
    parser.add_argument("--seed", type=int, default=1, help="random seed; the same seed gives an identical dataset")
    parser.add_argument(
        "--scale", type=float, default=1.0, help="shrink the protocol: trials per label and clip length times F (0 < F <= 1)"
    )
    parser.add_argument(
        "--jobs", type=int, default=min(4, os.cpu_count() or 1), help="parallel rendering processes (default: cores, at most 4)"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace recordings that already exist")
    parser.add_argument("--no-thermal", action="store_true", help="skip thermal.npz (the 8 Hz thermal channel)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    cond = registry.subcommand(
        "simulate",
        "condition",
        "Write labelled recordings of a condition of use (issue 17): litroom (room light variants, the still skin with the probe as the projector stream), face (whole curved face,"
        " by zone), faceon (the wearer's face on the skin, with the projector stream, in the dim and the lit room), multitouch (two hands, palm, hug).",
        _condition,
    )
    cond.add_argument("condition", choices=("litroom", "face", "faceon", "multitouch"), help="which condition")
    cond.add_argument("--out", required=True, help="dataset directory to write; one folder per variant, <condition>-<variant>")
    cond.add_argument(
        "--variants",
        help="comma-separated variants (litroom: dim,lit,switch-on,switch-off,drift,passer-by,too-bright; face: centre,mid,edge, and per"
        " zone ZONE-faceon, ZONE-lit, ZONE-faceon-lit (the wearer's face projected, the lit room, both); faceon:"
        " static,face,static-lit,face-lit; multitouch: one-finger,two-finger-v,two-hands-5cm,two-partners,swipe-cross,swipe-graze,palm,"
        "palm-and-finger,hug); default all (face: centre,mid,edge)",
    )
    cond.add_argument("--seed", type=int, default=1, help="random seed; the same seed gives identical recordings")
    cond.add_argument("--scale", type=float, default=0.1, help="trials times F (0 < F <= 1; litroom, faceon: the protocol's 228 trials, face: 5 per label and zone, multitouch: 6 runs per scene)")
    cond.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1), help="parallel rendering processes")
    cond.add_argument("--overwrite", action="store_true", help="replace recordings that already exist")
    cond.add_argument(
        "--clips", action="store_true",
        help="litroom, faceon: also the protocol's continuous contact, hover and empty clips, to fit the gates under the "
        "condition (calibrate touch, eval --fit-on-clips)",
    )
    cond.add_argument("--quiet", action="store_true", help="no progress lines")
    bench = registry.subcommand("bench", "sim", "Scene simulator render time per 640x480 frame, by scene, against an empty frame.", _bench)
    bench.add_argument("--frames", type=int, default=60, help="frames per scene")
    bench.add_argument("--json", help="also write the report here")


def _bench(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from feelium.lab.sim.bench import format_table, run_bench

    report = run_bench(frames=max(5, args.frames))
    print(format_table(report))
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    return 0


def _condition(args: argparse.Namespace) -> int:
    from feelium.lab.sim.conditions import simulate_condition

    name = f"feelium simulate condition {args.condition}"
    variants = tuple(v.strip() for v in args.variants.split(",") if v.strip()) if args.variants else None
    start = time.monotonic()

    def progress(done: int, total: int, path: str) -> None:
        if not args.quiet:
            print(f"[{done}/{total}] {path}", file=sys.stderr)

    try:
        written = simulate_condition(
            args.out, args.condition, variants=variants, seed=max(0, args.seed), scale=args.scale,
            jobs=max(1, args.jobs), overwrite=args.overwrite, progress=progress, clips=args.clips,
        )  # fmt: skip
    except ValueError as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        return 2
    except FileExistsError as exc:
        print(f"{name}: {exc} (use --overwrite to replace)", file=sys.stderr)
        return 1
    print(f"wrote {len(written)} recordings to {args.out} in {time.monotonic() - start:.1f} s")
    return 0


def _paper_protocol(args: argparse.Namespace) -> int:
    from feelium.lab.sim.protocol import simulate_protocol

    if not (0.0 < args.scale <= 1.0):
        print(f"feelium simulate paper-protocol: --scale must be in (0, 1], got {args.scale}", file=sys.stderr)
        return 2
    if args.seed < 0:
        print("feelium simulate paper-protocol: --seed must be >= 0", file=sys.stderr)
        return 2
    start = time.monotonic()

    def progress(done: int, total: int, path: str) -> None:
        if not args.quiet:
            print(f"[{done}/{total}] {path}", file=sys.stderr)

    try:
        written = simulate_protocol(
            args.out, seed=args.seed, scale=args.scale, jobs=max(1, args.jobs), overwrite=args.overwrite,
            thermal=not args.no_thermal, progress=progress,
        )
    except FileExistsError as exc:
        print(f"feelium simulate paper-protocol: {exc} (use --overwrite to replace)", file=sys.stderr)
        return 1
    print(f"wrote {len(written)} recordings to {args.out} in {time.monotonic() - start:.1f} s")
    return 0
