"""The flight tick's lateness histogram: every tick counted once, percentiles as bin upper bounds."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.flight.lateness import EDGES_MS, LatenessHistogram, counts_between, percentile_ms


def test_each_lateness_lands_in_the_bin_it_does_not_exceed():
    hist = LatenessHistogram()
    for late_s in (-0.001, 0.0, 0.0005, 0.0006, 0.004, 0.25):
        hist.record(late_s)
    counts = hist.snapshot()["counts"]
    assert counts[0] == 3  # early, on time and exactly 0.5 ms
    assert counts[1] == 1 and counts[EDGES_MS.index(5.0)] == 1 and counts[-1] == 1
    assert percentile_ms(EDGES_MS, counts, 50) == 0.5
    assert percentile_ms(EDGES_MS, counts, 99) == math.inf
    assert percentile_ms(EDGES_MS, [0] * len(counts), 99) is None


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 0.3, allow_nan=False), min_size=1, max_size=300), st.sampled_from([50.0, 90.0, 99.0]))
def test_the_percentile_bounds_the_exact_one_from_above_by_at_most_one_bin(lates, q):
    hist = LatenessHistogram()
    for late in lates:
        hist.record(late)
    counts = hist.snapshot()["counts"]
    assert sum(counts) == len(lates)
    bound = percentile_ms(EDGES_MS, counts, q)
    exact = 1000.0 * float(np.percentile(lates, q, method="inverted_cdf"))
    assert bound >= exact
    edges = [0.0, *EDGES_MS, math.inf]
    below = edges[edges.index(bound) - 1]
    assert exact > below or exact == 0.0  # the exact value lies inside the reported bin


def test_a_window_is_the_difference_of_two_snapshots():
    hist = LatenessHistogram()
    hist.record(0.0001)
    first = hist.snapshot()["counts"]
    for _ in range(99):
        hist.record(0.012)
    hist.record(0.04)
    window = counts_between(first, hist.snapshot()["counts"])
    assert sum(window) == 100
    assert percentile_ms(EDGES_MS, window, 50) == 15.0 and percentile_ms(EDGES_MS, window, 100) == 50.0
