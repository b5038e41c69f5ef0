"""The dead-man motion path shared by the headset API, the interactions and the flight controller.

A wearer's command only moves the blimp while it keeps being refreshed: a
frozen headset or a dropped Wi-Fi link therefore stops the body within the
hold time, without any code having to notice the failure. Time is an input
(``now``), so the rule is testable without a clock.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Literal, get_args

MotionName = Literal["forward", "backward", "up", "down", "turn_left", "turn_right", "stop"]
MOTION_NAMES: tuple[str, ...] = get_args(MotionName)
# Commands that only ever bring the blimp to rest: never rate limited, never refused for want of control.
NEUTRAL_NAMES: frozenset[str] = frozenset({"stop"})
DEFAULT_HOLD_S = 0.5
MAX_HOLD_S = 0.5  # the flight goal: stopped within 1.5 s of the last refresh, of which braking takes up to 1.0 s


@dataclass(frozen=True)
class MotionCommand:
    """What the wearer asked for, when, and until when it stands."""

    name: str
    issued_at: float
    expires_at: float
    source: str


class DeadManCommands:
    """Holds the newest motion command and lets it lapse when not refreshed.

    Commands are set on the event loop and read by flight's control step on its serial thread: a
    lock makes a lapse and a refresh exclusive, so a lapse seen on one thread never clears the
    command another thread has just refreshed (uncontended, it costs a fraction of a microsecond).
    """

    def __init__(self, max_hold_s: float = MAX_HOLD_S) -> None:
        self.max_hold_s = max_hold_s
        self._current: MotionCommand | None = None
        self._lock = threading.Lock()
        self.accepted = 0
        self.expired = 0

    def command(self, name: str, now: float, hold_s: float = DEFAULT_HOLD_S, source: str = "headset") -> MotionCommand:
        """Set (or refresh) a command; ``stop`` clears motion at once."""
        if name not in MOTION_NAMES:
            raise ValueError(f"unknown motion {name!r}; expected one of {', '.join(MOTION_NAMES)}")
        if not (math.isfinite(hold_s) and 0.0 < hold_s <= self.max_hold_s):
            raise ValueError(f"hold must be in (0, {self.max_hold_s}] seconds, got {hold_s}")
        cmd = MotionCommand(name=name, issued_at=now, expires_at=now + hold_s, source=source)
        with self._lock:
            self._current = None if name in NEUTRAL_NAMES else cmd
            self.accepted += 1
        return cmd

    def active(self, now: float) -> MotionCommand | None:
        """The command in force at ``now``, or ``None`` (hold position)."""
        cmd = self._current
        if cmd is None or now < cmd.expires_at:
            return cmd
        with self._lock:
            current = self._current
            if current is cmd:  # not refreshed meanwhile (on another thread): it lapses, once
                self._current = None
                self.expired += 1
                return None
        return current if current is not None and now < current.expires_at else None
