"""What each part's health really is, and one log line each time it changes.

The supervisor knows whether a service's task runs; only the service knows
whether it does its job (a motor board that never answers, a thermal sensor
whose reads all fail, a camera that went silent). :func:`judge` combines the
two into one state per part, and :class:`HealthTracker` remembers when that
state last changed and logs the change once, at a level that matches it, so
the journal tells the same story as ``/health`` without repeating itself.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)

# ok: doing its job on hardware; simulated: doing its job on a simulator (or a replay);
# degraded: running but not fully doing its job; failed: not doing it (crashed, missing, cannot build);
# starting: not yet known; stopped: shut down.
STATES = ("ok", "simulated", "degraded", "failed", "starting", "stopped")
BAD_STATES = ("degraded", "failed")
OWN_CONDITIONS = ("ok", "degraded", "failed", "starting")
# stopped: the supervisor already logs each service it stops, so the change is only worth a debug line
LOG_LEVELS = {"failed": logging.ERROR, "degraded": logging.WARNING, "stopped": logging.DEBUG}


def judge(task: str, own: dict[str, Any], simulated: str | None, crash: str | None, retry_in_s: float | None) -> tuple[str, str | None]:
    """One part's state and reason from its task state, its own ``condition``/``reason`` and its backend.

    A crashed task outranks whatever the service last said about itself; a
    simulated part that works says so, but a simulated part in trouble shows
    the trouble.
    """
    if task == "starting":
        return "starting", None
    if task == "backoff":
        return "failed", f"crashed ({crash}); restarting in {retry_in_s or 0.0:.1f} s"
    if task == "failed":
        return "failed", f"gave up restarting after crashes ({crash})"
    if task == "stopped":
        return "stopped", None
    if task == "finished":
        # Every part of the daemon is meant to run until shutdown: one whose task returned (a replay that
        # ended without looping) no longer does its job, whatever it last said about itself.
        return "degraded", "finished its work: its input ended and it no longer runs"
    else:
        condition = own.get("condition", "ok")
        reason = own.get("reason")
        if condition not in OWN_CONDITIONS:
            condition, reason = "degraded", f"health reports an unknown condition {condition!r}"
    if condition == "ok" and simulated is not None:
        return "simulated", simulated
    return condition, reason


@dataclass
class PartHealth:
    """A part's current state, since when, and the newest trouble it had (kept after it recovers)."""

    state: str
    reason: str | None
    since: float  # monotonic
    changed_at: float  # wall clock, to match the journal
    last_problem: str | None = None
    last_problem_at: float | None = None  # monotonic


class HealthTracker:
    """Per-part state with the time of its last change; each change is logged once."""

    def __init__(self, clock: Callable[[], float] = time.monotonic, wall: Callable[[], float] = time.time) -> None:
        self.clock = clock
        self.wall = wall
        self.parts: dict[str, PartHealth] = {}

    def update(self, part: str, state: str, reason: str | None) -> PartHealth:
        """Record ``state``; a new state (not a new wording of the same one) is logged."""
        now = self.clock()
        current = self.parts.get(part)
        if current is None or current.state != state:
            previous = current.state if current is not None else None
            fresh = PartHealth(state, reason, now, self.wall())
            if current is not None:
                fresh.last_problem, fresh.last_problem_at = current.last_problem, current.last_problem_at
            current = self.parts[part] = fresh
            if previous is not None or state != "starting":
                detail = f": {reason}" if reason else ""
                was = f" (was {previous})" if previous else ""
                log.log(LOG_LEVELS.get(state, logging.INFO), "%s: %s%s%s", part, state, detail, was)
        else:
            current.reason = reason
        if state in BAD_STATES:
            current.last_problem, current.last_problem_at = reason, now
        return current

    def entry(self, part: str) -> dict[str, Any]:
        """The part's state fields for the health report."""
        health = self.parts[part]
        now = self.clock()
        return {
            "state": health.state,
            "reason": health.reason,
            "since_s": round(now - health.since, 3),
            "changed_at": round(health.changed_at, 3),
            "healthy": health.state in ("ok", "simulated"),
            "last_problem": health.last_problem,
            "last_problem_age_s": None if health.last_problem_at is None else round(now - health.last_problem_at, 3),
        }


def overall(states: dict[str, str], vital: frozenset[str] = frozenset()) -> str:
    """The daemon's status from its parts' states: ``failed`` when a vital part (flight) failed, so a monitor
    can tell a grounded blimp from a dropped camera frame; any other trouble is ``degraded``; all good is ``ok``."""
    if any(states.get(name) == "failed" for name in vital):
        return "failed"
    if any(state in BAD_STATES for state in states.values()):
        return "degraded"
    if any(state == "starting" for state in states.values()):
        return "starting"
    return "ok"
