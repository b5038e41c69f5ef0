"""Rolling minimum over time: agrees with brute force, windows by time not frames."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.touch.rolling import RollingMin


@given(
    st.lists(
        st.tuples(st.floats(0.0, 0.6, allow_nan=False), st.floats(0.0, 1.0, allow_nan=False)),
        min_size=1,
        max_size=80,
    ),
    st.floats(0.05, 2.0),
)
def test_matches_brute_force_minimum_over_the_time_window(steps, window):
    rolling = RollingMin(window)
    t = 0.0
    history = []
    for dt, value in steps:
        t += dt
        history.append((t, value))
        got = rolling.push(t, value)
        expected = min(v for ts, v in history if ts > t - window)
        assert got == expected


def test_a_gap_longer_than_the_window_forgets_everything_before_it():
    rolling = RollingMin(1.0)
    rolling.push(0.0, 0.1)
    rolling.push(0.5, 0.9)
    assert rolling.push(3.0, 0.8) == 0.8


def test_window_is_time_not_frames():
    rolling = RollingMin(1.0)
    for k in range(30):  # 30 frames at 30 fps: the 0.0 at t=0 is still inside after 0.97 s
        got = rolling.push(k / 30, 0.0 if k == 0 else 0.5)
    assert got == 0.0
    assert rolling.push(1.01, 0.5) == 0.5


def test_backwards_time_is_rejected():
    rolling = RollingMin(1.0)
    rolling.push(1.0, 0.5)
    with pytest.raises(ValueError, match="backwards"):
        rolling.push(0.5, 0.5)


def test_deque_stays_small_for_increasing_values():
    rolling = RollingMin(1.0)
    for k in range(1000):
        rolling.push(k / 15, k / 1000)
    assert len(rolling) <= 16
