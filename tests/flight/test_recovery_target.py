"""Back from an outage past an altitude limit, the hold aims a margin inside the limit, not onto it.

The board's watchdog stops the motors during a stall or a dropped link and the buoyant body floats to the room's
ceiling; the descent back is flown on a heave side no window has taught. Held at the limit itself, every bounce of
that descent counted against the limits' 10 cm: 6 of 128 fault cases on the corners (worst 0.29 m) and 21 of 272 on
random plants (docs/flight-robustness.md, session 36).
"""

from __future__ import annotations

import dataclasses

import pytest

from feelium.daemon.config import Config
from feelium.flight.controller import FlightController
from feelium.flight.loops import RECOVERY_MARGIN_M, recovery_target
from feelium.flight.setpoint import HOLD, Setpoint

CONFIG = Config().flight
DT = 1.0 / CONFIG.rate_hz


@pytest.mark.parametrize("z", [CONFIG.altitude_min_m, 1.3, CONFIG.altitude_max_m])
def test_inside_the_limits_the_recovery_holds_where_the_body_is(z: float) -> None:
    assert recovery_target(CONFIG, z) == z


def test_past_a_limit_the_recovery_aims_the_margin_inside_it() -> None:
    assert recovery_target(CONFIG, CONFIG.altitude_max_m + 0.4) == pytest.approx(CONFIG.altitude_max_m - RECOVERY_MARGIN_M)
    assert recovery_target(CONFIG, CONFIG.altitude_min_m - 0.3) == pytest.approx(CONFIG.altitude_min_m + RECOVERY_MARGIN_M)


def test_between_close_limits_the_margin_is_a_quarter_of_their_span() -> None:
    """Limits 0.4 m apart: a 0.2 m margin from either would be their middle; a quarter keeps the two apart."""
    close = dataclasses.replace(CONFIG, altitude_min_m=1.0, altitude_max_m=1.4)
    assert recovery_target(close, 2.0) == pytest.approx(1.3)
    assert recovery_target(close, 0.5) == pytest.approx(1.1)


def _loop_past_the_ceiling(recovering: bool) -> FlightController:
    """A controller whose hold was restarted at the ceiling limit, with the body 0.3 m over it and still."""
    controller = FlightController(CONFIG)
    obs, loop = controller.altitude, controller.altitude_loop
    obs.z, obs.vz = CONFIG.altitude_max_m + 0.3, 0.0
    loop.restart(CONFIG.altitude_max_m)
    if recovering:
        loop.recover(0.0)
    return controller


def _step(controller: FlightController, t: float, setpoint: Setpoint = HOLD) -> None:
    controller.altitude_loop.step(t, DT, setpoint, controller.altitude, controller.thrust, 1.0, False)


def test_a_recovering_hold_past_the_ceiling_aims_the_margin_below_it() -> None:
    recovering = _loop_past_the_ceiling(recovering=True)
    _step(recovering, 1.0)
    assert recovering.altitude_loop.target == pytest.approx(CONFIG.altitude_max_m - RECOVERY_MARGIN_M)


def test_a_hold_past_the_ceiling_without_an_outage_holds_the_limit() -> None:
    """A climb that overshot the ceiling limit by a little is not pulled down by the margin: only an outage's is."""
    steady = _loop_past_the_ceiling(recovering=False)
    _step(steady, 1.0)
    assert steady.altitude_loop.target == pytest.approx(CONFIG.altitude_max_m)


def test_a_climb_command_ends_the_recovery() -> None:
    controller = _loop_past_the_ceiling(recovering=True)
    _step(controller, 1.0, Setpoint(climb_m_s=-CONFIG.climb_rate_m_s))
    assert not controller.altitude_loop.recovering
