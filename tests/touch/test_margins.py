"""Margins of the gates: hardest negative and hardest positive against each threshold (issue 17, point 5)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.lab.touch.margins import GateSeries, GateThresholds, gate_margin, margins
from feelium.recording import Contact

GATES = GateThresholds(contact_edge=0.05, instant_depth=0.55, anchor_threshold=0.30, anchor_min_age_s=0.5)
T = np.arange(0.0, 4.0, 0.1)


def _series(anchor, core, edge, contacts=(), negative=False):
    full = lambda v: np.full(T.size, v, float) if np.isscalar(v) else np.asarray(v, float)  # noqa: E731
    return GateSeries(T, full(anchor), full(core), full(edge), tuple(contacts), negative)


def test_hardest_cases_and_signed_margins_per_gate():
    deep_hover = _series(0.10, np.where(T > 2, 0.52, 0.2), 0.046, negative=True)  # 0.52 deep: 0.03 below
    blurred_hover = _series(0.0, 0.50, 0.03, negative=True)  # no contact edge: held off by the edge gate
    tap_core = np.where((T >= 1.0) & (T < 1.3), 0.58, 0.0)
    tap = _series(np.where(tap_core > 0, 0.5, 0.0), tap_core, 0.06, [Contact(1.0, 1.3, None)])
    hold = _series(np.where(T >= 1.5, 0.35, 0.0), np.where(T >= 1.0, 0.62, 0.0), 0.06, [Contact(1.0, 3.0, None)])
    m = margins([deep_hover, blurred_hover, tap, hold], GATES, widen=(0.2, 0.5))
    assert m["instant"]["hardest_negative"] == pytest.approx(0.52)
    assert m["instant"]["negative_margin"] == pytest.approx(0.03)
    assert m["instant"]["hardest_positive"] == pytest.approx(0.58)  # the tap is the shallower press
    assert m["instant"]["positive_margin"] == pytest.approx(0.03)
    assert (m["instant"]["negatives"], m["instant"]["positives"]) == (2, 2)
    assert m["edge"]["negative_margin"] == pytest.approx(0.004)  # the sharpest hover, 0.004 short of landing
    assert m["edge"]["positive_margin"] == pytest.approx(0.01)
    # The tap (0.3 s) is shorter than anchor_min_age_s: not a positive of the sustained gate.
    assert m["sustained"]["positives"] == 1
    assert m["sustained"]["hardest_positive"] == pytest.approx(0.35)
    assert m["sustained"]["negative_margin"] == pytest.approx(0.20)


def test_a_positive_scores_only_inside_its_widened_contact():
    late = _series(np.zeros(T.size), np.where(T >= 3.5, 0.9, 0.0), 0.06, [Contact(1.0, 1.5, None)])
    assert margins([late], GATES, widen=(0.2, 0.5))["instant"]["hardest_positive"] == 0.0
    assert margins([late], GATES, widen=(0.2, 2.5))["instant"]["hardest_positive"] == pytest.approx(0.9)


def test_each_press_of_a_clip_is_its_own_positive():
    core = np.where((T >= 0.5) & (T < 1.5), 0.7, 0.0) + np.where((T >= 2.0) & (T < 3.0), 0.4, 0.0)
    clip = _series(0.0, core, 0.06, [Contact(0.5, 1.5, None), Contact(2.0, 3.0, None)])
    assert margins([clip], GATES)["instant"]["hardest_positive"] == pytest.approx(0.7)
    per_press = margins([clip], GATES, per_contact=True)["instant"]
    assert (per_press["positives"], per_press["hardest_positive"]) == (2, pytest.approx(0.4))


def test_no_sample_is_null_not_invented():
    m = gate_margin([], [], 0.3)
    assert m["hardest_negative"] is None and m["positive_margin"] is None


@given(st.lists(st.floats(0, 1), min_size=1, max_size=20), st.lists(st.floats(0, 1), min_size=1, max_size=20), st.floats(0, 1))
def test_both_margins_are_positive_exactly_when_the_threshold_separates(neg, pos, threshold):
    m = gate_margin(neg, pos, threshold)
    separates = max(neg) < threshold and min(pos) > threshold
    assert (m["negative_margin"] > 0 and m["positive_margin"] > 0) == separates


def test_the_projector_light_gate_counts_only_frames_whose_share_was_known():
    gates = GateThresholds(0.05, 0.55, 0.30, 0.5, contact_projected_depth=0.2)
    unknown = np.full(T.size, np.nan)
    hover = _series(0.0, 0.7, 0.06, negative=True)
    hover = GateSeries(hover.t, hover.anchor, hover.core_depth, hover.edge, (), True, np.where(T > 1, -0.05, np.nan))
    blind = GateSeries(T, hover.anchor, hover.core_depth, hover.edge, (), True, unknown)  # the share never learned
    tap = _series(0.5, 0.6, 0.06, [Contact(1.0, 1.3, None)])
    press = np.where((T >= 1.0) & (T < 1.3), 0.45, np.nan)
    press[T > 3.5] = 0.9  # outside the widened contact: not the tap's score
    tap = GateSeries(T, tap.anchor, tap.core_depth, tap.edge, tap.contacts, False, press)
    m = margins([hover, blind, tap], gates, widen=(0.2, 0.5))
    assert (m["projected"]["negatives"], m["projected"]["positives"]) == (1, 1)
    assert m["projected"]["negative_margin"] == pytest.approx(0.25)
    assert m["projected"]["positive_margin"] == pytest.approx(0.25)
    assert m["instant"]["negatives"] == 2  # the other gates still count the blind recording
    assert "projected" not in margins([hover, tap], GATES)  # the gate off: no margin reported for it
