"""Touch events gain projector coordinates and regions through the calibration."""

import math

import numpy as np
import pytest

from feelium.skin.annotation import annotate
from feelium.interactions.config import InteractionsConfig
from feelium.skin.regions import Regions
from feelium.skin.projector_map import default_calibration
from tests.interactions.touches import ROI, at_uv, event

CAL = default_calibration((640, 480), ROI, (1280, 720))
REGIONS = Regions.from_config(InteractionsConfig())


@pytest.mark.parametrize(
    "u, v, region",
    [(0.5, 0.2, "head"), (0.27, 0.58, "cheek_left"), (0.73, 0.58, "cheek_right"), (0.5, 0.85, "palm_zone"), (0.1, 0.45, "skin")],
)
def test_region_and_projector_point(u, v, region):
    x, y = at_uv(u, v)
    out = annotate(event(3, "down", 1.0, x, y), CAL, REGIONS)
    assert out.extra["region"] == region
    expected = CAL.to_projector(x, y)
    assert (out.extra["px"], out.extra["py"]) == pytest.approx(expected, abs=0.06)
    assert out.to_json()["region"] == region and out.id == 3


def test_default_map_is_affine_and_centred():
    px, py = CAL.to_projector(*at_uv(0.5, 0.5))
    assert (px, py) == pytest.approx((640, 360), abs=1.5)


def test_off_the_patch_has_no_projector_point():
    out = annotate(event(1, "down", 1.0, 10.0, 10.0), CAL, REGIONS)
    assert out.extra["px"] is None and out.extra["region"] is None


def test_to_projector_is_bilinear_between_pixels():
    a = np.array(CAL.to_projector(200.0, 200.0))
    b = np.array(CAL.to_projector(201.0, 200.0))
    mid = np.array(CAL.to_projector(200.5, 200.0))
    assert mid == pytest.approx((a + b) / 2)
    assert CAL.to_projector(math.nan, 3.0) is None
