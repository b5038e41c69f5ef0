"""What the skin shows in answer: the renderer's input from the interaction engine.

An answer is a drawable thing at a skin-canvas position ``(u, v)`` with a
start time and an end time (``math.inf`` while the touch that caused it
lasts). It carries no pixels: the renderer decides how a ripple looks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

AnswerKind = Literal[
    "ripple",  # expanding rings where a tap landed
    "warm_pulse",  # a warm glow swelling and fading at a spot
    "heart",  # a small heart blooming at a spot
    "palm_glow",  # a palm-shaped glow; detail side=partner|wearer, merged=bool, from_u/from_v for the wearer's glide
    "breathing",  # the whole skin glowing slowly in and out
    "shimmer",  # an inviting shimmer travelling over the skin
    "stroke",  # a live finger stroke; detail points=((u, v), ...)
    "ignite",  # the drawing bursting into flame; detail strokes=(((u, v), ...), ...)
    "prompt",  # a short text for the partner; detail text
]


@dataclass(frozen=True)
class Answer:
    kind: AnswerKind
    t0: float
    u: float
    v: float
    until: float = math.inf
    detail: dict[str, Any] = field(default_factory=dict, compare=False)

    def age(self, now: float) -> float:
        return now - self.t0

    def alive(self, now: float) -> bool:
        return now < self.until
