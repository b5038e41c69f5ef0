"""The pacing of simulated cameras and the newest-wins hand-over from camera threads."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from feelium.cameras.base import Frame, Pacer
from feelium.cameras.reader import FrameSlot, RateMeter, Worker, pump


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


def _frame(i: int) -> Frame:
    return Frame(t=float(i), image=np.zeros((2, 2), np.uint8))


async def test_slot_keeps_the_newest_frame_and_counts_the_ones_it_replaced():
    slot = FrameSlot()
    for i in range(5):
        slot.put(_frame(i))
    taken = await slot.take()
    assert taken is not None and taken.t == 4.0
    assert slot.dropped == 4
    slot.end()
    assert await slot.take() is None


async def test_slot_hands_over_what_is_left_before_reporting_the_end():
    slot = FrameSlot()
    slot.put(_frame(1))
    slot.end()
    first = await slot.take()
    assert first is not None and first.t == 1.0
    assert await slot.take() is None


class ListCamera:
    name = "list"

    def __init__(self, n: int, realtime: bool) -> None:
        self.frames = [_frame(i) for i in range(n)]
        self.realtime = realtime

    def read(self) -> Frame | None:
        return self.frames.pop(0) if self.frames else None

    def close(self) -> None:
        pass


async def test_pump_of_an_on_demand_source_loses_nothing_for_a_slow_consumer():
    slot = FrameSlot()
    worker = Worker("test")
    task = asyncio.create_task(pump(ListCamera(20, realtime=False), slot, worker))
    seen = []
    while (frame := await slot.take()) is not None:
        seen.append(frame.t)
        await asyncio.sleep(0.001)  # slower than the camera
    await task
    worker.shutdown()
    assert seen == [float(i) for i in range(20)]
    assert slot.dropped == 0


class RaisingCamera(ListCamera):
    def read(self) -> Frame | None:
        if not self.frames:
            raise OSError("unplugged")
        return super().read()


async def test_pump_ends_the_slot_and_raises_when_the_camera_fails():
    slot = FrameSlot()
    worker = Worker("test")
    task = asyncio.create_task(pump(RaisingCamera(2, realtime=True), slot, worker))
    while await slot.take() is not None:
        pass
    with pytest.raises(OSError, match="unplugged"):
        await task
    worker.shutdown()
