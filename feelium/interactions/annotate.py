"""Touch events gain projector coordinates and their envelope region (for the touch service to call)."""

from __future__ import annotations

import dataclasses

from feelium.events import TouchEvent
from feelium.interactions.regions import Regions
from feelium.projector.calibration import CalibrationMap


def skin_uv(calibration: CalibrationMap, x: float, y: float) -> tuple[float, float]:
    """Camera pixel to skin-canvas position (0..1 across the calibrated ROI)."""
    rx, ry, rw, rh = calibration.roi
    return (x - rx) / rw, (y - ry) / rh


def annotate(event: TouchEvent, calibration: CalibrationMap, regions: Regions) -> TouchEvent:
    """A copy of ``event`` with extra keys ``px``, ``py`` (projector pixels, None off the map) and ``region``.

    The event's camera ``x``/``y`` must be in the calibration's camera pixels.
    """
    where = calibration.to_projector(event.x, event.y)
    u, v = skin_uv(calibration, event.x, event.y)
    extra = dict(event.extra)
    extra["px"] = None if where is None else round(where[0], 1)
    extra["py"] = None if where is None else round(where[1], 1)
    extra["region"] = regions.region_at(u, v)
    return dataclasses.replace(event, extra=extra)
