"""Telemetry from one burst's replies: each decoded, a bad payload counted and left out, never raised."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from feelium.flight import messages as m
from feelium.flight.msp import MspFrame
from feelium.flight.telemetry import Telemetry

_M = TypeVar("_M")


def decode_telemetry(replies: dict[int, MspFrame], t: float) -> tuple[Telemetry, int]:
    """The telemetry the replies carry, stamped ``t``, and how many payloads could not be decoded.

    Straight-line, every reply looked up once: it runs every control tick (a closure and a dict of
    keyword arguments per call cost as much as the decoding).
    """
    get = replies.get
    rng, bad_rng = _decoded(get(m.MSP_SONAR_ALTITUDE), m.Rangefinder.decode)
    att, bad_att = _decoded(get(m.MSP_ATTITUDE), m.Attitude.decode)
    imu, bad_imu = _decoded(get(m.MSP_RAW_IMU), m.RawImu.decode)
    flow, bad_flow = _decoded(get(m.MSP2_SENSOR_OPTIC_FLOW), m.OpticFlow.decode)
    analog, bad_analog = _decoded(get(m.MSP_ANALOG), m.Analog.decode)
    moving = flow is not None and flow.quality > 0
    telemetry = Telemetry(
        t,
        range_m=None if rng is None else rng.distance_m,
        heading_deg=None if att is None else att.heading_deg,
        yaw_rate_dps=None if imu is None else float(imu.gyro_dps[2]),
        roll_deg=None if att is None else att.roll_deg,
        pitch_deg=None if att is None else att.pitch_deg,
        battery_v=None if analog is None else analog.voltage_v,
        flow_x_rad_s=flow.x_rad_s if moving else None,
        flow_y_rad_s=flow.y_rad_s if moving else None,
        flow_quality=None if flow is None else flow.quality,
    )
    return telemetry, bad_rng + bad_att + bad_imu + bad_flow + bad_analog


def _decoded(frame: MspFrame | None, decoder: Callable[[bytes], _M]) -> tuple[_M | None, int]:
    """The frame's payload decoded, and 1 when it does not decode (counted as bad); no value and nothing bad for a
    missing reply or an error reply (the board said it has no such value)."""
    if frame is None or frame.direction == "!":
        return None, 0
    try:
        return decoder(frame.payload), 0
    except m.PayloadError:
        return None, 1
