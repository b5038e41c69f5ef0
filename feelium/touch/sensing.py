"""Can the rear camera see shadows at all? The touch service's verdict on its own light, for health.

A touch pipeline that cannot see is silent, and silence looks exactly like a
membrane nobody touches. Three things blind it, each measured on every frame
from what the pipeline already computes:

- **Saturation**: a pixel at the camera's ceiling cannot show how much light
  a hand takes away (``depth.py`` masks it). A room or a projector so bright
  that the exposure cannot bring most of the membrane under the ceiling leaves
  no membrane to sense.
- **Darkness**: a pixel whose expected light is under ``dark_reference_level``
  carries no information (masked too). A projector that is off or shows black
  for long leaves the membrane unlit.
- **Room light** that outshines the projector: the projector's share of the
  membrane's light, learned online from projected content
  (``photometric.ProjectorResponse.share``). A contact's own contrast (the
  frustrated reflection of the projector's light in the film) scales with
  that share, while a hovering hand's shadow of the room light deepens with
  the room. Measured, touch holds down to the share of a room 8x the
  projector's (``MIN_PROJECTOR_SHARE``, where the share reaches its floor);
  below it nothing vouches for touch, and it says so instead of firing or
  going quiet unannounced.
- **Room light that outshines the projector in places**: the membrane's mean
  share can hide a corner lit far more by the room (a dim corner of the
  back-light near the lamp). Where the projector's share of the light is
  known per place (:mod:`feelium.touch.roomshare`), the pipeline counts the
  membrane whose share is under the same measured floor
  (:func:`feelium.touch.roomshare.room_dominated`); over
  ``ROOM_DOMINATED_SHARE`` of the membrane, touch says so.
- **The share not learned**: while the projector's probe (or compensated
  content) should teach the share and it is still unknown, the hover gate
  cannot act and a close hover in a lit room may fire; touch says so until
  the share is learned (a few probe periods).

A condition must hold for ``HOLD_S`` before it is reported (a fade to black or
a lamp's warm-up is not a fault) and clears as soon as the light is back.
Pure: counts and times in, a condition out.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from feelium.touch.roomshare import MEASURED_SHARE_FLOOR

BLIND_SHARE = 0.5  # more than half the membrane masked: most touches would fall where nothing can be seen
HOLD_S = 2.0  # a condition reported only once it has lasted this long
# The learned share at the brightest room measured to work (8x the projector's light): below it, nothing vouches for
# touch (roomshare.MEASURED_SHARE_FLOOR; until session 19 1/3, set on another quantity, which called every lit
# living room degraded where touch found every press and fired no hover).
MIN_PROJECTOR_SHARE = MEASURED_SHARE_FLOOR
# A quarter of the membrane beyond anything measured: one touch in four would land where nothing vouches for it.
ROOM_DOMINATED_SHARE = 0.25
# Each condition's name in short, for reports that count them (``feelium eval``); health's reasons say more.
PROBLEMS = {
    "saturated": "too bright",
    "dark": "too dark",
    "room_light": "room light outshines the projector",
    "room_local": "room light outshines the projector in places",
    "share_unknown": "projector's share not learned",
}


@dataclass(frozen=True)
class SensingSample:
    """One frame's light, as the pipeline saw it."""

    t: float
    pixels: int  # working pixels considered
    dark: int
    saturated: int
    projector_share: float | None  # None until projected content has taught it
    room_dominated: float | None = None  # share of the membrane the room outshines locally; None: share not known
    share_taught: bool = False  # the probe or compensated content is teaching the share (so it should become known)


class SensingMonitor:
    """Turns per-frame light figures into a sustained health condition with its reason."""

    def __init__(self, hold_s: float = HOLD_S) -> None:
        self.hold_s = hold_s
        self.last: SensingSample | None = None
        self._since: dict[str, float] = {}  # problem -> when it began, while it lasts

    def update(self, sample: SensingSample) -> None:
        self.last = sample
        for problem, present in self._problems(sample).items():
            if present:
                self._since.setdefault(problem, sample.t)
            else:
                self._since.pop(problem, None)

    def present(self) -> set[str]:
        """The conditions of the last frame, lasting or not (keys of :data:`PROBLEMS`)."""
        return set(self._since) if self.last is not None else set()

    def lasting(self) -> set[str]:
        """The conditions that have lasted ``hold_s``: what health reports as ``degraded``."""
        s = self.last
        if s is None:
            return set()
        return {p for p, since in self._since.items() if s.t - since >= self.hold_s}

    @staticmethod
    def _problems(s: SensingSample) -> dict[str, bool]:
        share = s.projector_share
        return {
            "saturated": s.pixels > 0 and s.saturated > BLIND_SHARE * s.pixels,
            "dark": s.pixels > 0 and s.dark > BLIND_SHARE * s.pixels,
            "room_light": share is not None and share < MIN_PROJECTOR_SHARE,
            "room_local": s.room_dominated is not None and s.room_dominated > ROOM_DOMINATED_SHARE,
            "share_unknown": s.share_taught and s.room_dominated is None,
        }

    def reasons(self) -> list[str]:
        """What blinds touch now, for at least ``hold_s`` (empty when it can see)."""
        s = self.last
        if s is None:
            return []
        lasting = self.lasting()
        out = []
        if "saturated" in lasting:
            out.append(f"too bright to see shadows: {100 * s.saturated / s.pixels:.0f} % of the membrane is saturated")
        if "dark" in lasting:
            out.append(f"too dark to see shadows: {100 * s.dark / s.pixels:.0f} % of the membrane is unlit")
        if "room_light" in lasting and s.projector_share is not None:
            out.append(
                f"room light outshines the projector ({100 * s.projector_share:.1f} % of the membrane's light is "
                f"projected, under {100 * MIN_PROJECTOR_SHARE:.1f} %, the brightest room measured to work): contacts "
                "and close hovers may look alike"
            )
        if "room_local" in lasting and s.room_dominated is not None:
            out.append(
                f"room light outshines the projector beyond the brightest room measured to work on "
                f"{100 * s.room_dominated:.0f} % of the membrane (over {100 * ROOM_DOMINATED_SHARE:.0f} %): contacts there "
                "may be lost or close hovers fire"
            )
        if "share_unknown" in lasting:
            out.append(
                "the projector's share of the membrane's light is not learned yet: in a lit room a close hover may "
                "fire as a touch"
            )
        return out

    def figures(self) -> dict[str, float | None]:
        """The last frame's light, in percent, for health (always shown, also when fine)."""
        s = self.last
        if s is None or s.pixels <= 0:
            return {
                "saturated_pct": None, "unlit_pct": None, "projector_share": None, "room_dominated_pct": None,
                "share_learned": None,
            }  # fmt: skip
        return {
            "saturated_pct": round(100.0 * s.saturated / s.pixels, 1),
            "unlit_pct": round(100.0 * s.dark / s.pixels, 1),
            "projector_share": None if s.projector_share is None else round(s.projector_share, 3),
            "room_dominated_pct": None if s.room_dominated is None else round(100.0 * s.room_dominated, 1),
            "share_learned": s.room_dominated is not None,
        }


def share_taught(contact_projected_depth: float, light_fed: bool) -> bool:
    """Whether something teaches the pipeline the projector's share of the light (the probe, or projected content it
    compensates: ``light_fed``) for a hover gate that is on (``contact_projected_depth`` > 0): its share must then
    become known."""
    return contact_projected_depth > 0.0 and light_fed


def sample_of(pipeline: Any, t: float, share_taught: bool) -> SensingSample | None:
    """What the monitor needs from a pipeline that just processed the frame of time ``t`` (None for a pipeline that
    does not count its masked pixels). Shared by the touch service and ``eval``'s replay, so both judge the same."""
    masked, geometry = getattr(pipeline, "masked", None), getattr(pipeline, "geometry", None)
    if masked is None or geometry is None:
        return None
    response = getattr(pipeline, "response", None)
    width, height = geometry.work_size
    return SensingSample(
        t=t, pixels=int(width * height), dark=masked.dark, saturated=masked.saturated,
        projector_share=None if response is None else response.share,
        room_dominated=getattr(pipeline, "room_dominated", None),
        share_taught=share_taught,
    )  # fmt: skip
