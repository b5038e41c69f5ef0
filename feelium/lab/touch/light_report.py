"""What ``eval`` adds about the light (issue 17, point 2): health's verdict per frame, and recovery after a switch.

Both are added keys of the evaluation report (the spec allows them), per condition and overall:

- ``light``: over the frames of the trials proper (from 0 s; a recorded warm-up is judged, as the daemon would,
  but not counted), the share of frames on which each condition of :mod:`feelium.touch.sensing` was present, the
  share on which it had lasted long enough for health to say ``degraded``, and how many recordings health would
  have called degraded at some frame, by reason. The judge is the touch service's own
  (:class:`~feelium.touch.sensing.SensingMonitor`, fed by :func:`~feelium.touch.sensing.sample_of` in
  :func:`feelium.lab.touch.replay.replay_recording`), with its hold: nothing here restates its thresholds.
- ``switch_recovery``: :func:`feelium.lab.touch.switch_recovery.summarise` of the switches measured.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from feelium.lab.touch.replay import ReplayResult
from feelium.lab.touch.switch_recovery import Switches, summarise
from feelium.touch.sensing import PROBLEMS


@dataclass(frozen=True)
class LightRecord:
    """One recording's light, as health judged it frame by frame."""

    frames: int
    present: dict[str, int]  # frames on which each condition was present
    degraded: dict[str, int]  # frames on which it had lasted ``HOLD_S``: health said degraded
    degraded_frames: int  # frames on which health said degraded for any reason

    @classmethod
    def of(cls, result: ReplayResult) -> LightRecord:
        keep = result.t >= 0.0 if (result.t >= 0.0).any() else np.ones(result.t.size, bool)
        present = {p: int(result.light_present[p][keep].sum()) for p in PROBLEMS if p in result.light_present}
        degraded = {p: int(result.light_degraded[p][keep].sum()) for p in PROBLEMS if p in result.light_degraded}
        anything = np.zeros(int(keep.sum()), bool)
        for p in degraded:
            anything |= result.light_degraded[p][keep]
        return cls(int(keep.sum()), present, degraded, int(anything.sum()))


@dataclass
class SwitchRecord:
    """One recording's light switches and the recovery measured after each (none when it has hands)."""

    switches: Switches
    recoveries: list[float] = field(default_factory=list)


def light_summary(records: list[LightRecord]) -> dict[str, Any] | None:
    """The ``light`` key: shares of frames per condition, and recordings health would have called degraded."""
    frames = sum(r.frames for r in records)
    if not frames:
        return None
    return {
        "frames": frames,
        "present_share": {PROBLEMS[p]: sum(r.present.get(p, 0) for r in records) / frames for p in PROBLEMS},
        "degraded_share": {PROBLEMS[p]: sum(r.degraded.get(p, 0) for r in records) / frames for p in PROBLEMS},
        "degraded_frames_share": sum(r.degraded_frames for r in records) / frames,
        "recordings": len(records),
        "recordings_degraded": sum(1 for r in records if r.degraded_frames),
        "recordings_degraded_by_reason": {PROBLEMS[p]: sum(1 for r in records if r.degraded.get(p, 0)) for p in PROBLEMS},
    }


def switch_summary(records: list[SwitchRecord]) -> dict[str, Any] | None:
    """The ``switch_recovery`` key (None when no recording has a switch)."""
    values = [v for r in records for v in r.recoveries]
    sources = [r.switches.source for r in records for _ in r.recoveries if r.switches.source is not None]
    unmeasurable = sum(len(r.switches.times) for r in records if not r.recoveries)
    return summarise(values, sources, unmeasurable)


def light_rows(light: dict[str, Any] | None, switch: dict[str, Any] | None) -> list[tuple[str, str]]:
    """The table's rows: health's verdict on the light, and recovery after a switch."""
    rows: list[tuple[str, str]] = []
    if light is not None:
        shares = ", ".join(f"{name} {100 * v:.0f} %" for name, v in light["present_share"].items() if v > 0.0)
        rows.append(("light: frames with a condition", shares or "none"))
        reasons = ", ".join(f"{name} {n}" for name, n in light["recordings_degraded_by_reason"].items() if n)
        rows.append(
            (
                "  health degraded",
                f"{light['recordings_degraded']} of {light['recordings']} recordings, "
                f"{100 * light['degraded_frames_share']:.0f} % of frames" + (f" ({reasons})" if reasons else ""),
            )
        )
    if switch is not None:
        rec = switch["recovery_s"]
        if rec is None:
            text = f"none measured ({switch['not_measurable']} switches in recordings with hands)"
        else:
            worst = "never" if rec["max"] is None else f"{rec['max']:.2f} s"
            median = "never" if rec["median"] is None else f"{rec['median']:.2f} s"
            goal = "yes" if switch["within_goal"] else "NO"
            text = (
                f"n {switch['n']}: median {median}, max {worst}, never {switch['never']}; within "
                f"{switch['goal_s']:.0f} s: {goal} ({switch['not_measurable']} not measurable: hands)"
            )
        rows.append(("recovery after a light switch", text))
    return rows
