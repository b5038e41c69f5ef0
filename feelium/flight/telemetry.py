"""What the controller knows about the blimp at one instant."""

from __future__ import annotations

from typing import NamedTuple


class Telemetry(NamedTuple):
    """One poll of the motor board; a field is ``None`` when its reply did not arrive or was invalid.

    A named tuple, not a frozen dataclass: one is built every control tick, and a frozen dataclass's
    ``__init__`` (one ``object.__setattr__`` per field, twelve here) cost three times as much.

    ``t`` is the Pi's clock when the replies were collected. ``range_m`` is
    the rangefinder's distance to the floor (``None`` when out of range).
    Heading is in degrees, clockwise seen from above; yaw rate likewise.
    ``flow_x_rad_s``/``flow_y_rad_s`` are the optical-flow sensor's angular
    rates (``None`` when it has no lock or no sensor is fitted); the
    controller turns them into ground speed with the rangefinder's height.
    """

    t: float
    range_m: float | None = None
    heading_deg: float | None = None
    yaw_rate_dps: float | None = None
    roll_deg: float | None = None
    pitch_deg: float | None = None
    battery_v: float | None = None
    baro_altitude_m: float | None = None
    motors_us: tuple[int, ...] | None = None
    flow_x_rad_s: float | None = None
    flow_y_rad_s: float | None = None
    flow_quality: int | None = None
