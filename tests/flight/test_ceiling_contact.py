"""Past the ceiling limit after an outage, the room's ceiling may be what stops the body: the heave learns nothing there.

During a stall or a dropped link the watchdog's motors off let the buoyant body float up into the room's ceiling; the
windows that spanned the contact credited its stop to the down pushes, and random-2026-27's down side was taught 2.65
where its truth is 0.58 (docs/flight-robustness.md, session 36).
"""

from __future__ import annotations

import pytest

from feelium.daemon.config import Config
from feelium.flight.controller import FlightController
from feelium.flight.estimators import AltitudeObserver
from tests.flight.still_readings import fly

CONFIG = Config().flight
DT = 1.0 / CONFIG.rate_hz


def _taught_windows(against_the_ceiling: bool) -> list[int]:
    """An observer fed 6 s of a body that answers the model exactly, its force stepping every 0.5 s (real excitation):
    how many windows taught each side."""
    obs = AltitudeObserver(CONFIG)
    z, vz = 1.5, 0.0
    for k in range(round(6.0 / DT)):
        t = k * DT
        force = -0.25 if (k * DT) % 1.0 < 0.5 else -0.45
        vz += obs.push(force) * DT
        z += vz * DT
        obs.update(t, z, force, DT)
        obs.learn(t, DT, force, against_the_ceiling=against_the_ceiling)
    return obs.effectiveness.samples


def test_windows_against_the_ceiling_teach_nothing() -> None:
    assert sum(_taught_windows(against_the_ceiling=False)) > 0  # the same pushes teach where nothing stops the body
    assert _taught_windows(against_the_ceiling=True) == [0, 0]


def test_the_controller_teaches_no_heave_window_while_a_recovery_is_past_the_ceiling() -> None:
    controller = FlightController(CONFIG)
    fly(controller, 0.0, 2.0, 1.5)
    fly(controller, 2.0, 3.0, None)  # a stall: the body floats up
    taught: list[bool] = []
    learn = controller.altitude.learn
    controller.altitude.learn = lambda *a, against_the_ceiling=False: (taught.append(against_the_ceiling),  # type: ignore[method-assign]
                                                                       learn(*a, against_the_ceiling=against_the_ceiling))
    fly(controller, 3.0, 3.5, CONFIG.altitude_max_m + 0.3)
    assert taught and all(taught)
    taught.clear()
    fly(controller, 3.5, 4.0, CONFIG.altitude_max_m - 0.3)  # back inside: once the estimate is, windows teach again
    assert taught and not any(taught[len(taught) // 2:])
