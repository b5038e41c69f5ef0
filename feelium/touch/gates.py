"""The touch gates, as plain decisions on one tracked shadow.

- Contact edge: skin on the membrane casts a shadow as sharp as the
  membrane's own scatter, a hand even 2 mm above it a shadow blurred by its
  height. A shadow *lands* on the first frame of a run with a contact edge;
  both gates below need a landed shadow, so a close hover that darkens almost
  like a touch (the paper's hard case) does not pass on depth alone.
- Instant depth gate: a landed core this deep is a firm press, confirmed at once.
- Sustained-anchoring gate (the paper's): a pressing fingertip stays pinned,
  so the rolling minimum of its core depth over the last second stays high,
  while a hovering hand wobbles and its shadow momentarily thins. The window
  counts from the landing, not from when the approaching hand's shadow first
  appeared: the approach is not wobble. The gate also needs the shadow landed
  for ``anchor_min_age_s``, so one frame is never evidence of sustain.
- While a contact is down it stays down as long as its core stays above
  ``release_depth`` and its edge above ``release_edge_fraction`` of the contact
  edge (hysteresis, so a swipe's motion blur does not split it, while a finger
  lifted to hover a few millimetres up, as between two pats, releases).

With ``contact_edge = 0`` every seen shadow counts as landed: the paper's two
gates alone.
"""

from __future__ import annotations

from feelium.touch.config import TouchConfig


def has_contact_edge(config: TouchConfig, edge: float) -> bool:
    """Whether a shadow's steepest gradient (depth per camera px) is sharp enough for skin on the membrane."""
    return edge >= config.contact_edge


def instant_gate(config: TouchConfig, core_depth: float) -> bool:
    return core_depth >= config.instant_depth


def sustained_gate(config: TouchConfig, anchor: float, landed_s: float) -> bool:
    return landed_s >= config.anchor_min_age_s and anchor > 0.0 and anchor >= config.anchor_threshold


def stays_down(config: TouchConfig, core_depth: float, edge: float) -> bool:
    """The release hysteresis of a contact that is down."""
    return core_depth >= config.release_depth and edge >= config.release_edge_fraction * config.contact_edge


def is_touching(
    config: TouchConfig,
    *,
    down: bool,
    seen: bool,
    landed_s: float | None,
    core_depth: float,
    edge: float,
    anchor: float,
) -> bool:
    """This frame's decision for one tracked shadow; ``landed_s`` is None when it has no contact edge now."""
    if not seen:
        return False
    if down:
        return stays_down(config, core_depth, edge)
    if landed_s is None:
        return False
    return instant_gate(config, core_depth) or sustained_gate(config, anchor, landed_s)
