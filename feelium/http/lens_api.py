"""``GET /lens``: the front fisheye's lens model, so the headset can place anything in the video it shows.

The model is assembled once at start (``feelium.cameras.select.front_lens``: the simulator's exact lens,
the calibrated file, or a nominal stand-in) and kept on the hub as plain JSON; this handler only serves it.
"""

from __future__ import annotations

from typing import Any

from aiohttp import web

from feelium.http.context import ctx
from feelium.http.errors import ApiError

LENS_SCHEMA: dict[str, Any] = {
    "type": "object",
    "required": ["model", "width", "height", "K", "D", "source", "rms_px"],
    "description": "OpenCV fisheye model (cv2.fisheye) of the front camera at the size of the served frames. "
    "Camera axes: x right, y down, z forward along the optical axis; pixel centres on integers. A direction "
    "theta off the axis at angle phi around it lands at pixel (fx * theta_d * cos(phi) + cx, fy * theta_d * "
    "sin(phi) + cy) with theta_d = theta * (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8).",
    "properties": {
        "model": {"const": "opencv_fisheye"},
        "width": {"type": "integer", "minimum": 1, "description": "Frame width the model is for (the video's)."},
        "height": {"type": "integer", "minimum": 1},
        "K": {
            "type": "array", "minItems": 3, "maxItems": 3, "description": "[[fx, 0, cx], [0, fy, cy], [0, 0, 1]], pixels.",
            "items": {"type": "array", "minItems": 3, "maxItems": 3, "items": {"type": "number"}},
        },
        "D": {"type": "array", "minItems": 4, "maxItems": 4, "items": {"type": "number"}, "description": "[k1, k2, k3, k4]."},
        "source": {
            "type": "string", "enum": ["sim", "calibrated", "nominal"],
            "description": "sim: the simulator's exact lens; calibrated: fitted by `feelium calibrate lens`; "
            "nominal: an uncalibrated 180-degree equidistant stand-in.",
        },
        "rms_px": {"type": ["number", "null"], "description": "RMS reprojection error of the calibration (pixels); null unless calibrated."},
        "skin_patch_deg": {
            "type": "array", "minItems": 2, "maxItems": 2, "items": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 180},
            "description": "Where touches are in this view: the skin's u, v (0..1, u right, v down) span these degrees of "
            "azimuth and elevation around the optical axis, (0.5, 0.5) on it. A touch at u, v is the direction "
            "azimuth = (u - 0.5) * skin_patch_deg[0], elevation = (0.5 - v) * skin_patch_deg[1] (up positive): "
            "camera axes (cos el sin az, -sin el, cos el cos az); project it with K and D. The envelope's geometry "
            "(the face centred on the front camera's axis) is assumed, not measured ([touch] face_azimuth_deg, face_elevation_deg).",
        },
    },
}  # fmt: skip


def openapi_paths() -> dict[str, Any]:
    """The path item of ``GET /lens`` for the OpenAPI document (kept here, beside its handler)."""
    return {"/lens": {"get": {
        "operationId": "lens",
        "summary": "The front camera's fisheye lens model (OpenCV K, D at the video's size).",
        "responses": {
            "200": {"description": "The lens.", "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Lens"}}}},
            "401": {"description": "Missing or wrong token.", "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Error"}}}},
            "403": {"description": "Host or Origin not allowed.", "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Error"}}}},
            "404": {"description": "The front camera is off.", "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Error"}}}},
        },
    }}}  # fmt: skip


async def get_lens(request: web.Request) -> web.Response:
    """The lens JSON; 404 ``no_lens`` when the front camera is off."""
    lens = ctx(request).hub.front_lens
    if lens is None:
        raise ApiError(404, "the front camera is off: there is no video to place anything in", "no_lens")
    return web.json_response(lens)
