"""The daemon's face model from ``[touch]``: one definition for the touch pipeline and the projector's canvas.

With ``face_model = "sphere"`` a touch's ``u``, ``v`` are azimuth and
elevation on the envelope (:mod:`feelium.skin.face`), so the projector must
draw its answers on a canvas in the same ``u``, ``v``; both sides build the
model here, for their own camera frame size, so they cannot disagree.
"""

from __future__ import annotations

from feelium.skin.face import FaceModel
from feelium.touch.config import TouchConfig


def face_for(config: TouchConfig, size: tuple[int, int]) -> FaceModel | None:
    """The face model for camera frames of ``size`` (width, height), or None when ``face_model = "none"``."""
    if config.face_model == "none":
        return None
    return FaceModel.for_frame(
        int(size[0]),
        int(size[1]),
        radius_mm=config.face_radius_mm,
        camera_behind_mm=config.face_camera_behind_mm,
        azimuth_deg=config.face_azimuth_deg,
        elevation_deg=config.face_elevation_deg,
    )
