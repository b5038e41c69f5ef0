"""Skin u,v has one definition, and the touch pipeline and the projector annotation both use it."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from feelium.events import TouchEvent
from feelium.interactions.config import InteractionsConfig
from feelium.skin.annotation import annotate
from feelium.skin.coords import inside_roi, skin_uv
from feelium.skin.projector_map import default_calibration
from feelium.skin.regions import Regions
from feelium.touch.config import TouchConfig
from feelium.touch.pipeline import TouchPipeline

ROI = (64, 48, 512, 384)


def test_u_v_run_from_the_first_pixels_outer_edge_to_the_last_pixels_outer_edge():
    assert skin_uv(ROI, 63.5, 47.5) == (0.0, 0.0)  # top-left edge of the ROI's first pixel
    assert skin_uv(ROI, 64 + 512 - 0.5, 48 + 384 - 0.5) == (1.0, 1.0)  # bottom-right edge of its last pixel
    assert skin_uv(ROI, 64.0, 48.0) == (0.5 / 512, 0.5 / 384)  # the first pixel's centre
    assert skin_uv(ROI, 64 + 255.5, 48 + 191.5) == (0.5, 0.5)  # the ROI's centre


@given(st.floats(-100, 800), st.floats(-100, 600))
def test_inside_roi_is_exactly_u_v_in_the_unit_square(x, y):
    u, v = skin_uv(ROI, x, y)
    assert inside_roi(ROI, x, y) == (0.0 <= u < 1.0 and 0.0 <= v < 1.0)


def test_the_pipelines_events_and_the_projector_annotation_agree_on_u_v():
    """A press seen by the real pipeline carries the u,v that skin_uv gives for its x,y, and its region is the one at that u,v."""
    size = (640, 480)
    pipeline = TouchPipeline(TouchConfig(), size, ROI)
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0 : size[1], 0 : size[0]]
    centre = (401.0, 207.0)
    press = np.exp(-((xx - centre[0]) ** 2 + (yy - centre[1]) ** 2) / (2 * 6.0**2))
    events: list[TouchEvent] = []
    for i in range(90):
        t = i / 30.0
        frame = np.full(size[::-1], 180.0) + rng.normal(0, 1.0, size[::-1])
        if 30 <= i < 75:
            frame *= 1.0 - 0.8 * press
        events += pipeline.process(t, np.clip(frame, 0, 255).astype(np.uint8)).events
    down = [e for e in events if e.phase == "down"]
    assert down, "the simulated press was not detected"
    e = down[0]
    assert (e.u, e.v) == skin_uv(ROI, e.x, e.y)
    regions = Regions.from_config(InteractionsConfig())
    calibration = default_calibration(size, ROI, (1280, 720))
    assert annotate(e, calibration, regions).extra["region"] == regions.region_at(e.u, e.v)
