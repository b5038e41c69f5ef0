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


def setpoint_for_motion(name: str | None, config: FlightConfig, soften: bool = False) -> Setpoint:
    """The setpoint for one of the six motion commands (``None`` or ``stop``: hold)."""
    speed, climb, yaw = config.forward_speed_m_s, config.climb_rate_m_s, config.yaw_rate_dps
    table = {
        "forward": Setpoint(forward_m_s=speed),
        "backward": Setpoint(forward_m_s=-speed),
        "up": Setpoint(climb_m_s=climb),
        "down": Setpoint(climb_m_s=-climb),
        "turn_left": Setpoint(yaw_rate_dps=-yaw),
        "turn_right": Setpoint(yaw_rate_dps=yaw),
    }
    chosen = table.get(name or "", HOLD)
    if soften:
        return Setpoint(soften=True)  # a partner is holding or hugging it: no wearer motion into them
    return chosen
