"""What the wearer (or a bench, or the interaction engine) asks the controller for."""

from __future__ import annotations

from dataclasses import dataclass

from feelium.flight.config import FlightConfig


@dataclass(frozen=True)
class Setpoint:
    """Rates while a command is held; absolute targets for station keeping; ``soften`` while touched.

    All zero means hold: the controller keeps the altitude and heading it
    had when the last command was released.
    """

    forward_m_s: float = 0.0
    climb_m_s: float = 0.0
    yaw_rate_dps: float = 0.0  # positive turns right (clockwise seen from above)
    altitude_m: float | None = None
    heading_deg: float | None = None
    soften: bool = False


HOLD = Setpoint()
SOFT = Setpoint(soften=True)  # a partner is holding or hugging it: no wearer motion into them

# Each motion command: the setpoint field it drives, the FlightConfig rate it drives it at, and the sign.
_MOTIONS = {
    "forward": ("forward_m_s", "forward_speed_m_s", 1.0),
    "backward": ("forward_m_s", "forward_speed_m_s", -1.0),
    "up": ("climb_m_s", "climb_rate_m_s", 1.0),
    "down": ("climb_m_s", "climb_rate_m_s", -1.0),
    "turn_left": ("yaw_rate_dps", "yaw_rate_dps", -1.0),
    "turn_right": ("yaw_rate_dps", "yaw_rate_dps", 1.0),
}


def setpoint_for_motion(name: str | None, config: FlightConfig, soften: bool = False) -> Setpoint:
    """The setpoint for one of the six motion commands (``None``, ``stop`` or an unknown name: hold).

    Called every control tick: only the chosen setpoint is built (building the six of the table each
    time was the tick's largest allocation), and hold and soften are shared constants (setpoints are frozen).
    """
    if soften:
        return SOFT
    motion = _MOTIONS.get(name or "")
    if motion is None:
        return HOLD
    field_name, rate_name, sign = motion
    return Setpoint(**{field_name: sign * getattr(config, rate_name)})
