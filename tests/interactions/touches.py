"""Touch-event sequences as the touch pipeline emits them, on the default 640x480 camera with ROI (64, 48, 512, 384)."""

from __future__ import annotations

from feelium.events import ContactKind, ContactShape, TouchEvent
from feelium.skin.coords import skin_uv

ROI = (64, 48, 512, 384)


def uv(x: float, y: float) -> tuple[float, float]:
    return skin_uv(ROI, x, y)


def at_uv(u: float, v: float) -> tuple[float, float]:
    """The camera pixel at skin position ``(u, v)`` (the inverse of :func:`skin_uv`)."""
    return ROI[0] + u * ROI[2] - 0.5, ROI[1] + v * ROI[3] - 0.5


def shape(contact: ContactKind, area_mm2: float | None = None) -> ContactShape:
    """What touched, as the pipeline's shape stage reports it (a round footprint)."""
    return ContactShape(contact, area_mm2, None, None, 1.0, 0.0)


def event(
    id: int, phase: str, t: float, x: float, y: float, area: int = 300, kind: str | None = None, contact: ContactShape | None = None
) -> TouchEvent:
    u, v = uv(x, y)
    return TouchEvent(
        id=id, phase=phase, kind=kind, t=t, x=x, y=y, u=u, v=v, depth=0.6, area=area, anchor=0.7, shape=contact  # type: ignore[arg-type]
    )


def tap(id: int, t: float, x: float, y: float) -> list[TouchEvent]:
    return [event(id, "down", t, x, y), event(id, "up", t + 0.15, x, y, kind="tap")]


def hold(
    id: int, t: float, x: float, y: float, duration: float, area: int, step: float = 0.1, contact: ContactShape | None = None
) -> list[TouchEvent]:
    events = [event(id, "down", t, x, y, area, contact=contact)]
    k = 1
    while k * step < duration:
        events.append(event(id, "move", t + k * step, x, y, area, contact=contact))
        k += 1
    events.append(event(id, "up", t + duration, x, y, area, kind="hold", contact=contact))
    return events


def swipe(
    id: int, t: float, points: list[tuple[float, float]], step: float = 0.07, contact: ContactShape | None = None
) -> list[TouchEvent]:
    events = [event(id, "down", t, *points[0], contact=contact)]
    for k, p in enumerate(points[1:], start=1):
        events.append(event(id, "move", t + k * step, *p, contact=contact))
    events.append(event(id, "up", t + len(points) * step, *points[-1], kind="swipe", contact=contact))
    return events
