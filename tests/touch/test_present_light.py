"""The projected-light gate reads a press against the projector's light present where it landed."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.touch.pipeline import PRESENT_LIGHT_FLOOR, _present_light
from feelium.touch.roomshare import projected_depth


def test_the_light_present_is_read_at_the_point_floored_and_capped() -> None:
    light = np.array([[0.2, 0.7], [1.6, np.nan]], np.float32)
    assert _present_light(None, (0.0, 0.0)) == 1.0  # no predicted light: the flat skin
    assert _present_light(light, (1.0, 0.0)) == pytest.approx(0.7)
    assert _present_light(light, (0.0, 0.0)) == PRESENT_LIGHT_FLOOR  # darker content: at most 1/floor more noise
    assert _present_light(light, (0.0, 1.0)) == 1.0  # brighter than flat: read as flat
    assert _present_light(light, (1.0, 1.0)) == 1.0  # unknown
    assert _present_light(light, (-5.0, 9.0)) == 1.0  # outside: the nearest pixel (1.6, capped)


@given(
    share=st.floats(0.05, 0.9),
    light=st.floats(PRESENT_LIGHT_FLOOR, 1.0),
    frustrated=st.floats(0.0, 1.0),
    blocked=st.floats(0.0, 1.0),
)
def test_a_press_reads_its_own_fraction_at_any_light_and_a_hover_stays_at_or_under_zero(
    share: float, light: float, frustrated: float, blocked: float
) -> None:
    # In the compensated frame the membrane is as under flat grey: the room gives 1 - share, the projector share.
    # Over content at ``light`` the projector's light present is share * light; a press takes ``frustrated`` of it.
    press = (1.0 - share) + share * light * frustrated
    assert projected_depth(press, share) / light == pytest.approx(frustrated, abs=1e-9)
    hover = blocked * (1.0 - share)  # a hand above takes only the room's light, at any content
    assert projected_depth(hover, share) / light <= 1e-9
