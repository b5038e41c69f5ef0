"""How well `feelium calibrate projector RECORDING` measures the projector's latency: the table of docs/projector.md
"Latency measured from the calibration recording (2026-11-27, session 18, branch i17lat)".

    PYTHONPATH=. python3 benchmarks/projector_latency.py [--seeds 5] [--pairs 10] [--out DIR]

Per true latency and seed, writes the simulator's calibration take (:mod:`feelium.lab.sim.take_calibration`,
``pairs`` binary stripe patterns with their inverses) and measures it: how many were measured or refused, the
largest error, and the CPU time of the measurement alone (median). Then, on the 80 ms take of seed 1 with its
meta's exposure removed, the latency when the camera's 30 ms exposure is taken as 20-40 ms.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from feelium.lab.projector.from_recording import recording_latency
from feelium.lab.projector.latency import LatencyError
from feelium.lab.sim.take_calibration import write_latency_take
from feelium.recording import Recording

TRUTHS_S = (0.0, 0.02, 0.033, 0.05, 0.08, 0.1, 0.133, 0.2, 0.35, 0.5)
EXPOSURE_S = 0.03  # the simulated sensor's


def stripes(pairs: int, size: tuple[int, int] = (1280, 720)) -> list[np.ndarray]:
    """Vertical binary stripes, coarsest first, each followed by its inverse."""
    w, h = size
    out = []
    for bit in range(1, pairs + 1):
        pattern = np.repeat(((np.arange(w) * 2**bit) // w % 2 * 255).astype(np.uint8)[None, :], h, axis=0)
        out += [pattern, 255 - pattern]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--pairs", type=int, default=10)
    parser.add_argument("--out", type=Path, help="keep the takes here (default: a temporary folder)")
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="latency-"))
    patterns = stripes(args.pairs)
    for true in TRUTHS_S:
        errors, refused, cpu = [], 0, []
        for seed in range(1, args.seeds + 1):
            path = write_latency_take(root / f"t{true}-{seed}", patterns, true, seed=seed)
            start = time.process_time()
            try:
                errors.append(abs(recording_latency(Recording(path), EXPOSURE_S).latency_s - true) * 1e3)
            except LatencyError:
                refused += 1
            cpu.append(time.process_time() - start)
        print(json.dumps({"true_ms": true * 1e3, "measured": len(errors), "refused": refused,
                          "max_error_ms": round(max(errors, default=float("nan")), 4), "cpu_s_median": round(float(np.median(cpu)), 3)}))  # fmt: skip
    path = root / "t0.08-1"
    meta = json.loads((path / "meta.json").read_text())
    meta["camera"].pop("exposure_s", None)
    (path / "meta.json").write_text(json.dumps(meta))
    for taken in (0.02, 0.025, 0.035, 0.04):
        try:
            estimate = recording_latency(Recording(path), taken)
            print(json.dumps({"true_ms": 80.0, "exposure_taken_ms": taken * 1e3, "latency_ms": round(estimate.latency_s * 1e3, 2),
                              "spread_ms": round(estimate.spread_s * 1e3, 2)}))  # fmt: skip
        except LatencyError as exc:
            print(json.dumps({"true_ms": 80.0, "exposure_taken_ms": taken * 1e3, "refused": str(exc)}))


if __name__ == "__main__":
    main()
