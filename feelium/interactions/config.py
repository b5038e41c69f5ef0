"""The ``[interactions]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from feelium.motion import MAX_HOLD_S
from feelium.settings import setting


@dataclass(frozen=True)
class InteractionsConfig:
    """Envelope regions and the rules of the six exchanges.

    Regions are ellipses ``[cu, cv, ru, rv]`` on the skin canvas, in 0..1
    across the camera's sensitive patch (the touch events' ``u``/``v``), which
    the calibration map carries to the projector; they match the default
    avatar's layout. Palms and hugs are the touch events' ``contact`` kinds
    (sized in mm by ``[touch] palm_min_area_mm2`` and ``hug_min_area_mm2``),
    not areas in camera pixels.
    """

    RETIRED_KEYS: ClassVar[dict[str, str]] = {
        "palm_area_px": "palms are the touch events' contact = \"palm\", sized by [touch] palm_min_area_mm2",
        "hug_area_px": "hugs are the touch events' contact = \"hug\", sized by [touch] hug_min_area_mm2",
    }

    enabled: bool = setting(True, "Run the interaction engine.")
    head: tuple[float, ...] = setting((0.5, 0.2, 0.3, 0.14), "Head (forehead) region [cu, cv, ru, rv].", min=0.0, max=1.0)
    cheek_left: tuple[float, ...] = setting((0.27, 0.58, 0.11, 0.09), "Left cheek region.", min=0.0, max=1.0)
    cheek_right: tuple[float, ...] = setting((0.73, 0.58, 0.11, 0.09), "Right cheek region.", min=0.0, max=1.0)
    palm_zone: tuple[float, ...] = setting(
        (0.5, 0.8, 0.36, 0.18), "Palm zone: where the wearer's raised palm appears.", min=0.0, max=1.0
    )
    pat_window_s: float = setting(1.5, "Taps on the head closer than this count as one greeting pat.", min=0.1, max=10.0)
    palm_hold_s: float = setting(
        0.6, "How long a palm contact (the touch event's contact = palm) must stay to count as a palm hold.", min=0.0, max=30.0
    )
    hug_hold_s: float = setting(
        1.5, "How long a hug contact (contact = hug) must last to start the breathing glow.", min=0.0, max=60.0
    )
    stroke_min_px: float = setting(
        25.0, "Path length (camera px) after which a moving contact is a drawing stroke.", min=1.0, max=10000.0
    )
    drawing_idle_s: float = setting(45.0, "A drawing round with no stroke or guess for this long ends.", min=1.0, max=3600.0)
    ignite_s: float = setting(3.0, "How long the ignited drawing burns before the round clears.", min=0.1, max=60.0)
    words: tuple[str, ...] = setting(
        ("heart", "sun", "cat|kitten|kitty", "house|home", "tree", "star", "fish", "flower", "moon", "boat|ship"),
        "Secret words of the drawing game; 'word|synonym|...' accepts the synonyms as correct guesses.",
    )
    seed: int = setting(7, "Seed of the secret-word draw (rounds are reproducible).", min=0)
    heart_reply_s: float = setting(
        10.0, "A wearer's heart within this long after a peck goes back to that cheek.", min=0.1, max=600.0
    )
    shimmer_s: float = setting(6.0, "How long the inviting shimmer lasts.", min=0.5, max=120.0)
    drift_hold_s: float = setting(0.5, "Forward motion of the 'drift closer' reply (at most the dead man's longest hold).", min=0.05, max=MAX_HOLD_S)
    bounce_hold_s: float = setting(0.4, "Each half (up, then down) of the 'gentle bounce' reply.", min=0.05, max=MAX_HOLD_S)
