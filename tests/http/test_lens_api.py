"""GET /lens: the front fisheye's model as the headset receives it."""

from __future__ import annotations

import json
import urllib.request

import cv2
import numpy as np
import pytest

from feelium.cameras.lens import FisheyeLens
from feelium.cameras.sim_front import sim_lens
from feelium.http.lens_api import LENS_SCHEMA

from tests.http.http_support import AUTH


async def test_lens_is_served_with_the_token_only(client, hub):
    hub.front_lens = sim_lens(640, 480).to_json()
    resp = await client.get("/api/v1/lens", headers=AUTH)
    body = await resp.json()
    assert resp.status == 200
    assert body["model"] == "opencv_fisheye" and body["source"] == "sim" and body["rms_px"] is None
    assert (body["width"], body["height"]) == (640, 480)
    assert body["K"][0][2] == 319.5 and body["D"] == [0.0, 0.0, 0.0, 0.0]
    assert FisheyeLens.from_json(body) == sim_lens(640, 480)
    assert (await client.get("/api/v1/lens")).status == 401


async def test_the_lens_says_where_the_skin_is_as_the_browser_places_it(client, hub):
    """``skin_patch_deg`` is the face's extent (feelium.skin.face) and the browser client's own default, so a
    native app places a touch's u, v in the dome exactly as the browser does."""
    from pathlib import Path

    from dataclasses import replace

    from feelium.daemon.assembly import build_front_camera
    from feelium.daemon.config import Config
    from feelium.skin.face import FaceModel

    assert build_front_camera(Config(), hub) is not None  # the sim front camera, off a Pi
    body = await (await client.get("/api/v1/lens", headers=AUTH)).json()
    face = FaceModel(640, 480, 200.0, 320.0, 240.0)
    assert body["skin_patch_deg"] == [face.azimuth_deg, face.elevation_deg]
    config = Config()
    build_front_camera(replace(config, touch=replace(config.touch, face_azimuth_deg=90.0)), hub)
    body = await (await client.get("/api/v1/lens", headers=AUTH)).json()
    assert body["skin_patch_deg"] == [90.0, face.elevation_deg]  # the configured face, not a constant
    lens_js = (Path(__file__).parents[2] / "feelium/http/static/lens.js").read_text()
    assert f"SKIN_PATCH_DEG = [{face.azimuth_deg:g}, {face.elevation_deg:g}]" in lens_js


async def test_no_front_camera_no_lens(client):
    resp = await client.get("/api/v1/lens", headers=AUTH)
    assert resp.status == 404 and (await resp.json())["error"] == "no_lens"


async def test_the_answer_matches_its_schema(client, hub):
    import jsonschema

    hub.front_lens = FisheyeLens(640, 480, 200.0, 201.0, 320.0, 240.0, (0.01, 0.0, 0.0, 0.0), "calibrated", 0.3).to_json()
    body = await (await client.get("/api/v1/lens", headers=AUTH)).json()
    jsonschema.validate(body, LENS_SCHEMA)
    doc = await (await client.get("/api/v1/openapi.json")).json()
    assert doc["components"]["schemas"]["Lens"] == LENS_SCHEMA and "/lens" in doc["paths"]


@pytest.mark.slow
def test_the_live_sim_daemon_serves_the_lens_of_the_frames_it_sends(live):
    def get(path: str) -> urllib.request.addinfourl:
        return urllib.request.urlopen(urllib.request.Request(f"{live.api}{path}", headers=live.auth), timeout=10)

    lens = FisheyeLens.from_json(json.load(get("/lens")))
    frame = cv2.imdecode(np.frombuffer(get("/video/front.jpg").read(), np.uint8), cv2.IMREAD_COLOR)
    assert lens.source == "sim" and frame.shape[:2] == (lens.height, lens.width)
