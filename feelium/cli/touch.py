"""Commands of the touch pipeline: replay, eval, calibrate touch, bench touch.

Heavy imports stay inside the handlers so `feelium --help` is quick on a Pi.
"""

from __future__ import annotations

import argparse

from feelium.cli import CommandRegistry


_CALIBRATION_HELP = (
    "camera-to-projector map (.npz), or a calibration recording to fit it from, for recordings with a projector "
    "stream (default: projector-calibration.npz or a recording with meta purpose projector-calibration beside the trials)"
)


def register(registry: CommandRegistry) -> None:
    replay = registry.command(
        "replay", "Run the touch pipeline over a recording or dataset; print events as JSON lines (exit 3: bad recordings skipped; 1: none usable).", _replay
    )
    replay.add_argument("path", help="a recording directory or a dataset (any tree of recordings)")
    replay.add_argument("--config", help="TOML config file (its [touch] section is used)")
    replay.add_argument("--annotate", metavar="OUT", help="write an annotated video (a directory for datasets)")
    replay.add_argument("--projector-calibration", metavar="FILE", help=_CALIBRATION_HELP)

    ev = registry.command("eval", "Score the touch pipeline on a labelled dataset (docs/evaluation.md; exit 3: bad recordings skipped; 1: none usable).", _eval)
    ev.add_argument("dataset", help="dataset directory")
    ev.add_argument("--json", metavar="REPORT", help="write the version-1 report as JSON here")
    ev.add_argument("--figure", metavar="PNG", help="anchoring figure (default: beside the report, or ./touch-anchoring.png)")
    ev.add_argument("--config", help="TOML config file (its [touch] section is used)")
    ev.add_argument("--projector-calibration", metavar="FILE", help=_CALIBRATION_HELP)
    ev.add_argument(
        "--by-condition",
        action="store_true",
        help="also score each condition alone (meta generator.condition, else the first folder; added as \"conditions\")",
    )
    ev.add_argument(
        "--paper-gates",
        action="store_true",
        help="also replay every recording as the paper's two gates alone (no contact edge, blind to the projected light) "
        "and report it beside this pipeline (added as \"paper_gates\"; twice the replay time)",
    )
    ev.add_argument(
        "--fit-on-clips",
        action="store_true",
        help="fit the gates' thresholds on the dataset's contact and hover clips first, then score with them",
    )

    cal = registry.subcommand(
        "calibrate", "touch", "Fit the touch gates' thresholds on a dataset's contact and hover clips (exit 3: bad recordings skipped; 1: none usable).", _calibrate
    )
    cal.add_argument("dataset", help="dataset directory holding continuous contact and hover clips")
    cal.add_argument("--out", metavar="FILE", help="write the [touch] TOML fragment here (default: print it)")
    cal.add_argument("--config", help="TOML config file to start from (its [projector] gives the optics for clips with a projector stream)")
    cal.add_argument("--projector-calibration", metavar="FILE", help=_CALIBRATION_HELP)

    bench = registry.subcommand(
        "bench", "touch", "Speed against accuracy of the touch pipeline at several working resolutions.", _bench
    )
    bench.add_argument("--dataset", help="dataset to use (default: simulate a small one into a temp dir)")
    bench.add_argument("--seed", type=int, default=1, help="simulator seed when simulating")
    bench.add_argument("--scale", type=float, default=0.1, help="simulator scale when simulating")
    bench.add_argument("--json", metavar="FILE", help="write the results as JSON here")
    bench.add_argument("--config", help="TOML config file (its [touch] section is the starting point)")
    bench.add_argument(
        "--by-condition",
        action="store_true",
        help="also one table per condition (meta.generator.condition, or the dataset's first folder), as eval --by-condition",
    )


def _replay(args: argparse.Namespace) -> int:
    from feelium.lab.touch.commands import run_replay

    return run_replay(args)


def _eval(args: argparse.Namespace) -> int:
    from feelium.lab.touch.commands import run_eval

    return run_eval(args)


def _calibrate(args: argparse.Namespace) -> int:
    from feelium.lab.touch.commands import run_calibrate

    return run_calibrate(args)


def _bench(args: argparse.Namespace) -> int:
    from feelium.lab.touch.bench import run_bench

    return run_bench(args)
