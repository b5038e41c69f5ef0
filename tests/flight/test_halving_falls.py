"""A learned effectiveness falls by at most half per window (``Effectiveness(halving_falls=True)``).

A lower value makes every push it normalises stronger, so one misread window must not multiply a push by five
(docs/flight-robustness.md, session 37); a side's first value, a margin, and a value rising are not held back.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.flight.effectiveness import Effectiveness

DT = 0.02


def _push_and_answer(estimator: Effectiveness, t0: float, seconds: float, push: float, gain: float,
                     rate: float = 0.0) -> tuple[float, float]:
    """Push steadily for ``seconds`` from ``t0`` on a body whose rate changes by ``gain * push`` a second; the time and
    rate at the end."""
    t = t0
    for _ in range(round(seconds / DT)):
        t += DT
        rate += gain * push * DT
        estimator.update(t, DT, push, rate)
    return t, rate


def _falls(halving: bool) -> list[tuple[float, float]]:
    """A side taught 2.0 by small pushes, then large pushes reading 0.25 (they outweigh the small ones in the least
    squares at once): (time, value) after the change."""
    estimator = Effectiveness(0.125, 4.0, halving_falls=halving)
    t, rate = _push_and_answer(estimator, 0.0, 2.0, 0.05, 2.0)
    assert math.isclose(estimator.value(1.0), 2.0, rel_tol=0.01)
    seen = []
    for _ in range(90):
        t, rate = _push_and_answer(estimator, t, DT, 1.0, 0.25, rate)
        seen.append((t, estimator.value(1.0)))
    return seen


def test_a_taught_side_falls_by_at_most_half_per_window() -> None:
    limited, free = _falls(True), _falls(False)
    window = Effectiveness(0.125, 4.0).window_s
    after_one_window = [v for t, v in limited if t <= 2.0 + window + 1e-9]
    assert min(after_one_window) >= 1.0 - 1e-9  # half of 2.0, not less
    assert min(v for t, v in free if t <= 2.0 + window + 1e-9) < 0.5  # without the limit the windows took it to 0.49
    # ...and it does get there, at the pace of a halving per window
    assert limited[-1][1] < 0.3 and math.isclose(limited[-1][1], free[-1][1], rel_tol=0.05)


def test_a_rise_is_not_held_back() -> None:
    estimator = Effectiveness(0.125, 4.0, halving_falls=True)
    t, rate = _push_and_answer(estimator, 0.0, 2.0, 0.05, 0.5)
    assert estimator.value(1.0) < 0.6
    _push_and_answer(estimator, t, 0.32, 1.0, 3.0, rate)
    assert estimator.value(1.0) > 2.0  # weaker pushes at once: the safe side


def test_a_sides_first_value_is_not_held_back() -> None:
    """A weak blimp's first brake learns its reverse side at once: from the box's strongest, nothing was learned."""
    estimator = Effectiveness(0.125, 4.0, halving_falls=True)
    _push_and_answer(estimator, 0.0, 0.4, -0.5, 0.25)
    assert estimator.value(-1.0) < 0.3


def test_a_mirrored_sides_first_window_falls_from_what_the_other_side_taught() -> None:
    """On a mirrored axis an untaught side pushes with the other side's value: its first own window lowers that by
    at most half (a light strong blimp's hover yaw went from 1.52 to 0.19 in one window: session 37)."""
    limited, free = (Effectiveness(0.125, 4.0, mirrored=True, halving_falls=h) for h in (True, False))
    for estimator in (limited, free):
        t, rate = _push_and_answer(estimator, 0.0, 2.0, -0.05, 1.5)
        assert math.isclose(estimator.value(1.0), 1.5, rel_tol=0.02)  # taken from the other side
        _push_and_answer(estimator, t, DT, 1.0, 0.25, rate)  # the first window with a net push this way
    assert free.value(1.0) < 0.15  # it read the box's weakest: the reverse pushes' answer is still in it
    assert limited.value(1.0) >= 0.75 - 1e-9  # half of what the side pushed with


def test_the_margin_follows_the_windows_unlimited() -> None:
    """A margin counting on a higher value than the windows show is the unsafe side: it is not held back."""
    limited, free = Effectiveness(0.125, 4.0, halving_falls=True), Effectiveness(0.125, 4.0)
    for estimator in (limited, free):
        t, rate = _push_and_answer(estimator, 0.0, 2.0, 0.05, 2.0)
        _push_and_answer(estimator, t, 0.3, 1.0, 0.25, rate)
    assert limited.value(1.0) > 2.0 * free.value(1.0)
    assert limited.assured(1.0) == free.assured(1.0)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.0, 0.3), st.booleans())
def test_no_cycle_more_than_halves_a_learned_value_and_it_never_leaves_the_box(seed: int, noise: float, mirrored: bool) -> None:
    """Random pushes held 0.3 s each on a body whose gain jumps about: a value a side pushed with (its own, or on a
    mirrored axis the other side's) falls by at most half in one cycle (the pace over a window is
    ``test_a_taught_side_falls_by_at_most_half_per_window``'s); only a side nothing had taught moves freely."""
    rng = np.random.default_rng(seed)
    estimator = Effectiveness(0.125, 4.0, mirrored=mirrored, halving_falls=True)
    t, rate = 0.0, 0.0
    for _ in range(40):
        push, gain = float(rng.uniform(-1.0, 1.0)), float(rng.uniform(0.1, 4.0))
        for _ in range(15):
            before = [estimator.value(-1.0), estimator.value(1.0)]
            taught = [estimator.is_taught(-1.0), estimator.is_taught(1.0)]
            t += DT
            rate += gain * push * DT
            estimator.update(t, DT, push, rate + noise * float(rng.standard_normal()))
            for old, new, was_taught in zip(before, (estimator.value(-1.0), estimator.value(1.0)), taught):
                assert 0.125 <= new <= 4.0
                if was_taught:
                    assert new >= 0.5 * old - 1e-9


def _confirmed_after_a_misread(halving: bool, mirrored: bool) -> tuple[float, float]:
    """A side confirmed at 2.0 by pushes that changed the rate, then one window of a large push the rate answered at
    0.25 (the side's first own window on a mirrored axis, taught from the other side): (confirmed before, after)."""
    estimator = Effectiveness(0.125, 4.0, confirming_change=0.01, mirrored=mirrored, halving_falls=halving)
    teach = -1.0 if mirrored else 1.0
    t, rate = _push_and_answer(estimator, 0.0, 2.0, 0.1 * teach, 2.0)
    before = estimator.confirmed(1.0)
    t, rate = _push_and_answer(estimator, t, 0.3, 0.0, 0.0, rate)  # a still moment: the next windows are one-signed
    _push_and_answer(estimator, t, 0.3, 1.0, 0.25, rate)
    return before, estimator.confirmed(1.0)


def test_what_a_large_push_counts_on_falls_by_at_most_half_per_window_too() -> None:
    """The confirmed value (what turns and brakes are normalised by) is limited as the learned one is, on its own side
    and on a mirrored side's first confirmation."""
    for mirrored in (False, True):
        before, limited = _confirmed_after_a_misread(True, mirrored)
        _, free = _confirmed_after_a_misread(False, mirrored)
        assert math.isclose(before, 2.0, rel_tol=0.02)
        assert free < 0.5 * before  # the misread, unlimited
        assert limited >= 0.25 * before - 1e-9  # at most two halvings: the first window, then a window's pace
        assert limited > free
