"""Touch events gain projector coordinates and their envelope region.

Done once, where touch events are published, so every consumer (projector,
interactions, HTTP clients) sees the same answer. The daemon's assembly gives
the touch service a :class:`ProjectorAnnotation` when a projector calibration
exists; the touch service itself knows nothing of projectors.
"""

from __future__ import annotations

import dataclasses

from feelium.events import TouchEvent
from feelium.skin.coords import skin_uv
from feelium.skin.face import FaceModel
from feelium.skin.projector_map import ProjectorMap
from feelium.skin.regions import Regions


def annotate(event: TouchEvent, calibration: ProjectorMap, regions: Regions, face: FaceModel | None = None) -> TouchEvent:
    """A copy of ``event`` with extra keys ``px``, ``py`` (projector pixels, None off the map) and ``region``.

    The event's camera ``x``/``y`` must be in the calibration's camera pixels. The region is looked up at the
    skin u, v the projector's canvas uses: across the calibration's ROI, or on the face with a face model (for
    the calibration's frame size), as the touch pipeline and the renderer do with the same model.
    """
    where = calibration.to_projector(event.x, event.y)
    if face is None:
        u, v = skin_uv(calibration.roi, event.x, event.y)
    else:
        fu, fv = face.to_uv(event.x, event.y)
        u, v = float(fu), float(fv)
    extra = dict(event.extra)
    extra["px"] = None if where is None else round(where[0], 1)
    extra["py"] = None if where is None else round(where[1], 1)
    extra["region"] = regions.region_at(u, v)
    return dataclasses.replace(event, extra=extra)


class ProjectorAnnotation:
    """:func:`annotate` for events in frames of any size, counting (never raising) what it cannot annotate.

    The calibration map is in its own camera pixels; events in frames of
    another size are scaled onto it (the events' own ``x``/``y`` stay in
    camera pixels).
    """

    def __init__(self, calibration: ProjectorMap, regions: Regions, face: FaceModel | None = None) -> None:
        self.calibration = calibration
        self.regions = regions
        self.face = face
        self.errors = 0
        self.last_error: str | None = None

    def __call__(self, event: TouchEvent, frame_size: tuple[int, int]) -> TouchEvent:
        cw, ch = self.calibration.camera_size
        fw, fh = frame_size
        scaled = event if (cw, ch) == (fw, fh) else dataclasses.replace(event, x=event.x * cw / fw, y=event.y * ch / fh)
        try:
            extra = annotate(scaled, self.calibration, self.regions, self.face).extra
        except Exception as exc:  # an odd event must not stop touches reaching the bus: publish it unannotated
            self.errors += 1
            self.last_error = f"{type(exc).__name__}: {exc}"
            return event
        return dataclasses.replace(event, extra=extra)
