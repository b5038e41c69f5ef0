"""Fitting the gates on clip series: the contact edge in the middle of the gap, depth thresholds after it."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.lab.touch.calibrate import ClipSeries, fit_centred_threshold, fit_edge, fit_gates


def test_a_clean_gap_is_split_in_the_middle():
    assert fit_centred_threshold(np.array([0.10, 0.12, 0.15]), np.array([0.02, 0.04, 0.06])) == pytest.approx(0.08)


def test_overlap_keeps_the_best_balanced_accuracy():
    pos = np.array([0.05, 0.10, 0.11, 0.12])
    neg = np.array([0.01, 0.02, 0.03, 0.06])
    threshold = fit_centred_threshold(pos, neg)
    # Best balanced accuracy (7/8) is reached for thresholds in (0.06, 0.10]: its middle is 0.08.
    assert threshold == pytest.approx(0.08)


@given(
    st.lists(st.floats(0.0, 1.0), min_size=1, max_size=30),
    st.lists(st.floats(0.0, 1.0), min_size=1, max_size=30),
)
def test_the_centred_threshold_is_never_worse_than_any_other(pos, neg):
    pos, neg = np.array(pos), np.array(neg)
    threshold = fit_centred_threshold(pos, neg)

    def ba(th):
        return np.mean(pos >= th) + np.mean(neg < th)

    candidates = np.concatenate([pos, neg, [2.0]])
    assert ba(threshold) >= max(ba(c) for c in candidates) - 1e-9


def _clip(label, values, contact):
    t = np.arange(values.size) / 15.0
    return ClipSeries(label, t, anchor=values, core_depth=values, edge=values / 5, contact=contact)


def test_fits_use_only_the_first_sixty_percent_and_name_what_is_missing():
    rng = np.random.default_rng(0)
    contact = np.concatenate([rng.uniform(0.6, 0.7, 60), np.full(40, 0.1)])  # the last 40 % must not count
    hover = rng.uniform(0.2, 0.4, 100)
    clips = [_clip("contact", contact, np.ones(100, bool)), _clip("hover", hover, np.zeros(100, bool))]
    edge = fit_edge(clips)
    assert hover.max() / 5 < edge < 0.6 / 5
    fit = fit_gates(clips, edge)
    assert hover[:60].max() < fit.anchor_threshold <= contact[:59].min()
    assert fit.values()["contact_edge"] == pytest.approx(edge, abs=1e-4)
    with pytest.raises(ValueError, match="'hover' clip"):
        fit_gates(clips[:1], edge)
