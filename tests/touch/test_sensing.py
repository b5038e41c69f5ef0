"""Touch says when it cannot see: a saturated, unlit or room-lit membrane is a sustained health condition."""

from __future__ import annotations

import numpy as np
import pytest

from feelium.cameras.base import Frame
from feelium.cameras.select import CameraSource
from feelium.hub import Hub
from feelium.touch.config import TouchConfig
from feelium.touch.sensing import HOLD_S, MIN_PROJECTOR_SHARE, ROOM_DOMINATED_SHARE, SensingMonitor, SensingSample
from feelium.touch.service import TouchService


def sample(t: float, *, dark: int = 0, saturated: int = 0, share: float | None = None) -> SensingSample:
    return SensingSample(t=t, pixels=1000, dark=dark, saturated=saturated, projector_share=share)


def test_a_condition_is_reported_only_once_it_has_lasted_and_clears_at_once() -> None:
    monitor = SensingMonitor()
    monitor.update(sample(0.0))
    for t in np.arange(1.0, 1.0 + HOLD_S, 0.1):  # saturated, but not for HOLD_S yet
        monitor.update(sample(float(t), saturated=700))
        assert monitor.reasons() == []
    monitor.update(sample(1.0 + HOLD_S, saturated=700))
    assert monitor.reasons() == ["too bright to see shadows: 70 % of the membrane is saturated"]
    monitor.update(sample(3.1 + HOLD_S, saturated=100))
    assert monitor.reasons() == []
    assert monitor.figures() == {
        "saturated_pct": 10.0, "unlit_pct": 0.0, "projector_share": None, "room_dominated_pct": None,
        "share_learned": False,
    }


def test_a_brief_fade_to_black_is_not_a_fault_but_a_long_one_is() -> None:
    monitor = SensingMonitor()
    for t in np.arange(0.0, HOLD_S - 0.2, 0.1):
        monitor.update(sample(float(t), dark=900))
    monitor.update(sample(HOLD_S - 0.1, dark=0))
    monitor.update(sample(HOLD_S + 0.5, dark=900))
    assert monitor.reasons() == []  # the dark spell restarted
    monitor.update(sample(2 * HOLD_S + 0.6, dark=900))
    assert monitor.reasons() == ["too dark to see shadows: 90 % of the membrane is unlit"]


@pytest.mark.parametrize("share, blind", [(None, False), (0.5, False), (0.05, True), (MIN_PROJECTOR_SHARE, False)])
def test_room_light_is_judged_only_once_the_projectors_share_is_known(share: float | None, blind: bool) -> None:
    monitor = SensingMonitor()
    monitor.update(sample(0.0, share=share))
    monitor.update(sample(HOLD_S, share=share))
    reasons = monitor.reasons()
    assert bool(reasons) is blind
    if blind:
        assert reasons[0].startswith(
            "room light outshines the projector (5.0 % of the membrane's light is projected, under 5.5 %, the brightest "
            "room measured to work)"
        )


@pytest.mark.parametrize(
    "dominated, blind", [(None, False), (ROOM_DOMINATED_SHARE, False), (ROOM_DOMINATED_SHARE + 0.01, True)]
)
def test_a_membrane_room_lit_in_places_is_reported_whatever_the_mean_share(dominated: float | None, blind: bool) -> None:
    monitor = SensingMonitor()
    for t in (0.0, HOLD_S):  # the mean share is fine: only the local rule can see it
        monitor.update(SensingSample(t=t, pixels=1000, dark=0, saturated=0, projector_share=0.5, room_dominated=dominated))
    reasons = monitor.reasons()
    assert bool(reasons) is blind
    if blind:
        assert reasons == [
            "room light outshines the projector beyond the brightest room measured to work on 26 % of the membrane "
            "(over 25 %): contacts there may be lost or close hovers fire"
        ]
        assert monitor.figures()["room_dominated_pct"] == 26.0


def test_half_the_membrane_masked_is_the_limit() -> None:
    monitor = SensingMonitor()
    monitor.update(sample(0.0, saturated=500, dark=500))  # exactly half of each: not more than half
    monitor.update(sample(HOLD_S, saturated=500, dark=500))
    assert monitor.reasons() == []


class ScriptedCamera:
    name = "scripted"
    realtime = False

    def __init__(self, frames: list[Frame]) -> None:
        self.frames = frames

    def read(self) -> Frame | None:
        return self.frames.pop(0) if self.frames else None

    def close(self) -> None:
        pass


def _membrane(t: float, value: int) -> Frame:
    """A 320x240 back-lit membrane with the camera's noise, at one brightness."""
    rng = np.random.default_rng(int(t * 1000))
    image = np.clip(rng.normal(value, 2.0, (240, 320)), 0, 255).astype(np.uint8)
    return Frame(t=t, image=image, segment=0, roi=(16, 12, 288, 216))


async def _health_after(levels: list[tuple[float, int]]) -> dict:
    """Run the real touch service over spans of (seconds, grey level) at 15 fps; its health at the end."""
    frames, t = [], 0.0
    for seconds, value in levels:
        for _ in range(int(seconds * 15)):
            t += 1 / 15
            frames.append(_membrane(t, value))
    hub = Hub()
    service = TouchService(CameraSource("scripted", lambda: ScriptedCamera(frames)), hub, TouchConfig())
    await service.run()
    return service.health()


async def test_the_service_reports_a_saturated_membrane_and_recovers() -> None:
    blinded = await _health_after([(1.0, 120), (HOLD_S + 0.5, 255)])
    assert blinded["condition"] == "degraded" and "too bright to see shadows" in blinded["reason"]
    assert blinded["light"]["saturated_pct"] > 95.0
    recovered = await _health_after([(1.0, 120), (HOLD_S + 0.5, 255), (0.5, 120)])
    assert recovered["condition"] == "ok" and recovered["light"]["saturated_pct"] == 0.0


def test_a_share_that_should_be_learned_and_is_not_is_reported_until_it_is() -> None:
    monitor = SensingMonitor()
    taught = lambda t, dominated: SensingSample(  # noqa: E731
        t=t, pixels=1000, dark=0, saturated=0, projector_share=None, room_dominated=dominated, share_taught=True
    )
    monitor.update(taught(0.0, None))
    monitor.update(taught(HOLD_S - 0.1, None))
    assert monitor.reasons() == []  # the probe's first periods: learning, not a fault
    monitor.update(taught(HOLD_S + 0.1, None))
    assert monitor.reasons() == [
        "the projector's share of the membrane's light is not learned yet: in a lit room a close hover may fire as a touch"
    ]
    assert monitor.figures()["share_learned"] is False
    monitor.update(taught(HOLD_S + 0.2, 0.05))
    assert monitor.reasons() == [] and monitor.figures()["share_learned"] is True
    # nothing teaches it (no probe, no compensated content, or the gate off): unknown is no fault
    monitor = SensingMonitor()
    for t in (0.0, 10.0):
        monitor.update(SensingSample(t=t, pixels=1000, dark=0, saturated=0, projector_share=None))
    assert monitor.reasons() == []
