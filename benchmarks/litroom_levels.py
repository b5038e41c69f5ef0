"""The lit room at several room-light levels: what touch does and what health says, with the learned share per frame.

    PYTHONPATH=$PWD python3 benchmarks/litroom_levels.py --levels 1 2 3 5 8 --seed 31 --scale 0.05 --out DIR

For each level (room light through the membrane, times the projector's), writes ``litroom``'s ``lit`` recordings
at that level under ``DIR/lN`` (``feelium simulate condition litroom --variants lit`` with ``litroom.LIT`` set),
evaluates them as ``feelium eval --by-condition`` does (``DIR/lN.json``), and prints the learned pooled share's
percentiles (1, 50, 99) over the trials' frames: the figures behind health's room-light limit (docs/touch.md,
*How bright a room health vouches for*). About 2 minutes a level at scale 0.05 on one core.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import feelium.lab.touch.litroom as litroom
import feelium.lab.touch.replay as replay
from feelium.cli import main as feelium
from feelium.lab.sim.conditions import simulate_condition


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=float, nargs="+", default=[1.0, 2.0, 3.0, 5.0, 8.0])
    parser.add_argument("--seed", type=int, default=31)
    parser.add_argument("--scale", type=float, default=0.05)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    shares: list[float] = []
    judged = replay.sample_of

    def recorded(pipeline, t, taught):  # eval's own sample, its share kept
        sample = judged(pipeline, t, taught)
        if sample is not None and sample.projector_share is not None and t >= 0.0:
            shares.append(sample.projector_share)
        return sample

    replay.sample_of = recorded
    for level in args.levels:
        litroom.LIT = level
        out = Path(args.out) / f"l{level:g}"
        simulate_condition(out, "litroom", variants=("lit",), seed=args.seed, scale=args.scale, overwrite=True)
        shares.clear()
        feelium(["eval", str(out), "--by-condition", "--json", str(out) + ".json"])
        p1, p50, p99 = np.percentile(shares, [1, 50, 99]) if shares else (np.nan,) * 3
        print(f"level {level:g}: learned share p1 / p50 / p99 {p1:.3f} / {p50:.3f} / {p99:.3f} over {len(shares)} frames")


if __name__ == "__main__":
    main()
