"""``feelium bench flight``: the issue's measures on the simulator, against an untuned PID, with plots.

Every number is measured on the simulator's true state, with the spec hardware
(reversible 3D propellers on the horizontal pair, ``propellers.py``); the six
commands are flown once more with one-direction horizontal propellers as a
what-if, so the reason for the spec stays visible. Wall-clock timing
of the controller step is reported too (median and p95 per step), because
the Pi has to afford 50 of them a second next to the touch pipeline.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from feelium.lab.flight import scenarios as sc
from feelium.lab.flight.baseline import BaselinePid
from feelium.flight.config import FlightConfig
from feelium.lab.flight.latency_floor import latency_floor, one_direction_horizontal_propellers
from feelium.flight.setpoint import Setpoint

MOTIONS = ("forward", "backward", "up", "down", "turn_left", "turn_right")
TARGETS = {
    "altitude_rms_still_m": 0.03,
    "altitude_rms_drafts_m": 0.08,
    "heading_rms_deg": 3.0,
    "climb_settling_s": 4.0,
    "climb_overshoot": 0.10,
    "latency_s": 0.100,
    "stop_s": 0.5,
}
WHAT_IF_GREY = (128, 128, 128)  # BGR: the ruled-out hardware, apart from the six spec lines


def step_timing(config: FlightConfig, steps: int = 2000) -> dict[str, float]:
    """Wall time of one controller step (median, p95) in microseconds, on logged telemetry."""
    flight = sc.new_flight(config, True)
    telemetry = []
    for _ in range(steps):
        telemetry.append(flight.client.poll())
        flight.clock.t += flight.period
        flight.board.advance_to(flight.clock.t)
    from feelium.flight.controller import FlightController

    controller = FlightController(config)
    durations = []
    hold = Setpoint(altitude_m=sc.START_ALTITUDE_M)
    for i, tel in enumerate(telemetry):
        start = time.perf_counter()
        controller.step(i * flight.period, tel, hold)
        durations.append(time.perf_counter() - start)
    us = np.asarray(durations) * 1e6
    return {"median_us": float(np.median(us)), "p95_us": float(np.percentile(us, 95))}


def run_bench(config: FlightConfig, out_dir: Path, seed: int = 1) -> dict[str, Any]:
    out_dir.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {"seed": seed, "targets": TARGETS}
    still = sc.hold(config, False, seed)
    drafts = sc.hold(config, True, seed)
    base_still = sc.hold(config, False, seed, controller=BaselinePid(config))
    base_drafts = sc.hold(config, True, seed, controller=BaselinePid(config))
    results["hold"] = {
        "altitude_rms_still_m": still.altitude_rms_m,
        "altitude_rms_drafts_m": drafts.altitude_rms_m,
        "heading_rms_still_deg": still.heading_rms_deg,
        "heading_rms_drafts_deg": drafts.heading_rms_deg,
        "roughness_still": still.roughness,
        "roughness_drafts": drafts.roughness,
    }
    results["baseline_pid"] = {
        "altitude_rms_still_m": base_still.altitude_rms_m,
        "altitude_rms_drafts_m": base_drafts.altitude_rms_m,
        "heading_rms_still_deg": base_still.heading_rms_deg,
        "heading_rms_drafts_deg": base_drafts.heading_rms_deg,
        "roughness_still": base_still.roughness,
        "roughness_drafts": base_drafts.roughness,
    }
    results["quietness_ratio_drafts"] = base_drafts.roughness / max(drafts.roughness, 1e-12)
    climb = sc.altitude_step(config, 0.3, seed)
    base_climb = sc.altitude_step(config, 0.3, seed, controller=BaselinePid(config))
    turn = sc.heading_step(config, 45.0, seed)
    results["climb_30cm"] = {"settling_s": climb.settling_s, "overshoot": climb.overshoot_fraction}
    results["climb_30cm_baseline"] = {"settling_s": base_climb.settling_s, "overshoot": base_climb.overshoot_fraction}
    results["heading_step_45deg"] = {"settling_s": turn.settling_s, "overshoot": turn.overshoot_fraction}
    motions = {name: sc.motion(config, name, seed=seed) for name in MOTIONS}
    results["motion"] = {name: _motion_row(config, None, r) for name, r in motions.items()}
    results["worst_latency_s"] = max(r.latency_s for r in motions.values())
    results["worst_stop_s"] = max(r.stop_s for r in motions.values())
    # What-if, the hardware the spec rules out: one-direction propellers on the horizontal pair.
    old_config, old_blimp = one_direction_horizontal_propellers(config)
    one_direction = {name: sc.motion(old_config, name, seed=seed, blimp=old_blimp) for name in MOTIONS}
    results["what_if_one_direction_horizontal_propellers"] = {
        "horizontal_reverse_ratio": old_config.horizontal_reverse_ratio,
        "motion": {name: _motion_row(old_config, old_blimp, r) for name, r in one_direction.items()},
        "worst_latency_s": max(r.latency_s for r in one_direction.values()),
        "worst_stop_s": max(r.stop_s for r in one_direction.values()),
    }
    results["horizontal_reverse_ratio"] = config.horizontal_reverse_ratio
    results["vertical_reverse_ratio"] = config.vertical_reverse_ratio
    results["controller_step"] = step_timing(config)
    results["plots"] = _plots(out_dir, climb, base_climb, turn, drafts, motions, one_direction["backward"])
    (out_dir / "flight-bench.json").write_text(json.dumps(results, indent=2, default=_json_default))
    return results


def _motion_row(config: FlightConfig, blimp: Any, result: sc.MotionResult) -> dict[str, float]:
    floor = latency_floor(result.command, config, blimp)
    return {
        "latency_s": result.latency_s,
        "stop_s": result.stop_s,
        "peak_fraction": result.peak_fraction,
        "roughness": result.roughness,
        "floor_closed_form_s": floor.closed_form_s,
        "floor_slew_limited_s": floor.slew_limited_s,
    }


def _json_default(value: Any) -> Any:
    if isinstance(value, float) and not np.isfinite(value):
        return None
    raise TypeError(repr(value))


def _plots(
    out_dir: Path,
    climb: sc.StepResult,
    base: sc.StepResult,
    turn: sc.StepResult,
    drafts: sc.HoldResult,
    motions: dict[str, sc.MotionResult],
    backward_one_direction: sc.MotionResult,
) -> list[str]:
    from feelium.lab.plot import Series, line_plot

    paths = [
        line_plot(
            out_dir / "flight-climb-step.png",
            [Series(climb.t, climb.values * 100, "controller"), Series(base.t, base.values * 100, "untuned PID")],
            title="30 cm climb (still air, true altitude)",
            xlabel="time since step (s)",
            ylabel="altitude (cm)",
            hlines=((climb.target * 100, "target"), (climb.target * 100 + 3, "+10 %"), (climb.target * 100 - 1.5, "-5 %")),
        ),
        line_plot(
            out_dir / "flight-heading-step.png",
            [Series(turn.t, turn.values, "controller")],
            title="45 degree heading step (true heading)",
            xlabel="time since step (s)",
            ylabel="heading (deg)",
            hlines=((turn.target, "target"),),
        ),
        line_plot(
            out_dir / "flight-hold-drafts.png",
            [Series(drafts.log["t"], (drafts.log["z"] - sc.START_ALTITUDE_M) * 100, "altitude error (cm)")],
            title="Altitude hold in drafts",
            xlabel="time (s)",
            ylabel="error (cm)",
            hlines=((0.0, "target"),),
        ),
        line_plot(
            out_dir / "flight-commands.png",
            [Series(r.t[r.t >= -0.5], r.fraction[r.t >= -0.5], name) for name, r in motions.items()],
            title=f"The six commands through the dead man (held 3 s, expired at {next(iter(motions.values())).expired_s:.1f} s)",
            xlabel="time since the command was issued (s)",
            ylabel="motion / commanded rate",
            hlines=((1.0, "commanded"), (0.1, "10 %: stopped below")),
        ),
        line_plot(
            out_dir / "flight-onsets.png",
            [_onset_series(r, name) for name, r in motions.items()]
            + [_onset_series(backward_one_direction, "backward, one-direction props (what-if)", color=WHAT_IF_GREY)],
            title="Onsets: motion in units of the latency threshold (crossing 1 = moving); target 100 ms",
            xlabel="time since the command was issued (ms)",
            ylabel="motion / (2 cm/s or 3 deg/s)",
            hlines=((1.0, "moving"),),
        ),
    ]
    return [str(p) for p in paths]


def _onset_series(result: sc.MotionResult, label: str, color: tuple[int, int, int] | None = None) -> Any:
    """The first 200 ms of a command in units of its latency threshold (crossing 1 is "moving")."""
    from feelium.lab.plot import Series

    window = (result.t >= -0.04) & (result.t <= 0.2)
    in_thresholds = result.fraction[window] * result.commanded / sc.MOTION_THRESHOLD[result.command]
    return Series(result.t[window] * 1000.0, in_thresholds, f"{label} {result.latency_s * 1000:.0f} ms", color)


def format_table(results: dict[str, Any]) -> str:
    hold, base = results["hold"], results["baseline_pid"]
    old = results["what_if_one_direction_horizontal_propellers"]
    rows = [
        ("altitude RMS, still air", f"{hold['altitude_rms_still_m'] * 100:.2f} cm", f"{base['altitude_rms_still_m'] * 100:.2f} cm", "<= 3 cm"),
        ("altitude RMS, drafts", f"{hold['altitude_rms_drafts_m'] * 100:.2f} cm", f"{base['altitude_rms_drafts_m'] * 100:.2f} cm", "<= 8 cm"),
        ("heading RMS, still air", f"{hold['heading_rms_still_deg']:.2f} deg", f"{base['heading_rms_still_deg']:.2f} deg", "<= 3 deg"),
        ("heading RMS, drafts", f"{hold['heading_rms_drafts_deg']:.2f} deg", f"{base['heading_rms_drafts_deg']:.2f} deg", "<= 3 deg"),
        ("30 cm climb settling (5 %)", f"{results['climb_30cm']['settling_s']:.2f} s", f"{results['climb_30cm_baseline']['settling_s']:.2f} s", "<= 4 s"),
        ("30 cm climb overshoot", f"{results['climb_30cm']['overshoot'] * 100:.1f} %", f"{results['climb_30cm_baseline']['overshoot'] * 100:.1f} %", "<= 10 %"),
        ("command-to-motion latency (worst)", f"{results['worst_latency_s'] * 1000:.0f} ms", "-", "<= 100 ms"),
        ("  same, one-direction horizontal props", f"{old['worst_latency_s'] * 1000:.0f} ms", "-", "what-if (ruled out)"),
        ("stop after dead man expires (worst)", f"{results['worst_stop_s']:.2f} s", "-", "<= 0.5 s"),
        ("roughness in drafts (sum dcmd^2 / s)", f"{hold['roughness_drafts']:.3f}", f"{base['roughness_drafts']:.1f}", f"{results['quietness_ratio_drafts']:.0f}x quieter"),
        ("controller step (median / p95)", f"{results['controller_step']['median_us']:.0f} / {results['controller_step']['p95_us']:.0f} us", "-", "-"),
    ]
    width = max(len(r[0]) for r in rows)
    lines = [f"{'measure':<{width}}  {'controller':>16}  {'untuned PID':>14}  target"]
    lines += [f"{a:<{width}}  {b:>16}  {c:>14}  {d}" for a, b, c, d in rows]
    lines.append("per command (latency ms / stop s): " + ", ".join(
        f"{k} {v['latency_s'] * 1000:.0f}/{v['stop_s']:.2f}" for k, v in results["motion"].items()
    ))
    lines.append("")
    lines.append(f"spec: horizontal reverse ratio {results['horizontal_reverse_ratio']:.2f} (3D props),"
                 f" vertical {results['vertical_reverse_ratio']:.2f}; what-if: horizontal {old['horizontal_reverse_ratio']:.2f}")
    lines.append(f"{'command':<11} {'latency':>8} {'floor':>6} {'closed':>7} {'peak':>6} {'rough':>6} {'stop':>5}   "
                 f"{'1-dir':>8} {'floor':>6}")
    for name, v in results["motion"].items():
        w = old["motion"][name]
        lines.append(
            f"{name:<11} {v['latency_s'] * 1000:6.1f}ms {v['floor_slew_limited_s'] * 1000:6.1f} {v['floor_closed_form_s'] * 1000:7.1f}"
            f" {v['peak_fraction'] * 100:5.1f}% {v['roughness']:6.3f} {v['stop_s']:5.2f}   {w['latency_s'] * 1000:6.1f}ms {w['floor_slew_limited_s'] * 1000:6.1f}"
        )
    lines.append("floor: best possible with the mixer and slew limits (ms); closed: full force at once through the 80 ms lag;"
                 " peak: fastest motion while held / commanded; rough: motor roughness of the run;"
                 " 1-dir: one-direction horizontal propellers (what-if), latency and floor")
    return "\n".join(lines)
