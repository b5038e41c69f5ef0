"""The two touch gates of the paper, as plain decisions on one tracked shadow.

- Instant depth gate: a core this deep is a firm press, confirmed at once.
- Sustained-anchoring gate: a pressing fingertip stays pinned, so the rolling
  minimum of its core depth over the last second stays high; a hovering hand
  wobbles and its shadow momentarily thins (or vanishes), pulling the minimum
  down. The score is 0 until the shadow has been seen for ``anchor_min_age_s``:
  before that there is no evidence of anchoring.
- While a contact is down it stays down as long as its core stays above
  ``release_depth`` (hysteresis, so a swipe's motion blur does not split it).
"""

from __future__ import annotations

from feelium.touch.config import TouchConfig


def anchoring_score(config: TouchConfig, rolling_min: float, age_s: float) -> float:
    """The sustained-anchoring score of a shadow seen for ``age_s`` with this window minimum."""
    return rolling_min if age_s >= config.anchor_min_age_s else 0.0


def instant_gate(config: TouchConfig, core_depth: float) -> bool:
    return core_depth >= config.instant_depth


def sustained_gate(config: TouchConfig, anchor: float) -> bool:
    return anchor > 0.0 and anchor >= config.anchor_threshold


def is_touching(config: TouchConfig, *, down: bool, seen: bool, core_depth: float, anchor: float) -> bool:
    """This frame's decision for one tracked shadow."""
    if not seen:
        return False
    if down:
        return core_depth >= config.release_depth
    return instant_gate(config, core_depth) or sustained_gate(config, anchor)
