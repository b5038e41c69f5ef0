"""The pacing of simulated cameras and the time-based rate meter (the hand-overs: test_handoff.py)."""

from __future__ import annotations

import pytest

from feelium.cameras.base import Pacer
from feelium.cameras.reader import RateMeter


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds


def test_pacer_sleeps_until_each_frame_is_due():
    clock = FakeClock()
    pacer = Pacer(10.0, clock=clock, sleep=clock.sleep)
    due = [pacer.wait() for _ in range(4)]
    assert due == pytest.approx([100.0, 100.1, 100.2, 100.3])
    assert clock.sleeps == pytest.approx([0.1, 0.1, 0.1])


def test_pacer_that_falls_behind_restarts_from_now_instead_of_bursting():
    clock = FakeClock()
    pacer = Pacer(10.0, clock=clock, sleep=clock.sleep)
    pacer.wait()
    clock.now += 1.0  # the reader stalled for ten frame times
    assert pacer.wait() == pytest.approx(101.0)
    assert pacer.late == 1
    assert pacer.wait() == pytest.approx(101.1)


def test_pacer_rejects_a_zero_rate():
    with pytest.raises(ValueError, match="fps"):
        Pacer(0.0)


def test_rate_meter_measures_frames_per_second():
    meter = RateMeter(window_s=1.0)
    assert meter.rate(0.0) == 0.0
    for i in range(40):
        meter.tick(i * 0.05)
    last = 39 * 0.05
    assert meter.rate(last) == pytest.approx(20.0)
    assert meter.rate(last + 0.04) == pytest.approx(20.0)  # inside the usual interval: still the true rate


def test_rate_meter_decays_to_zero_when_ticks_stop():
    """A stalled camera must not keep showing its last rate (it read 15 fps forever when the meter counted ticks)."""
    meter = RateMeter(window_s=1.0)
    for i in range(30):
        meter.tick(i / 15)
    last = 29 / 15
    assert meter.rate(last) == pytest.approx(15.0)
    rates = [meter.rate(last + dt) for dt in (0.2, 0.5, 0.8)]
    assert rates[0] < 15.0 and rates == sorted(rates, reverse=True)  # falls as the gap grows
    assert meter.rate(last + 1.0) == 0.0
