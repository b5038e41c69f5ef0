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
    bad = 0
    range_m = heading = roll = pitch = yaw_rate = battery_v = flow_x = flow_y = flow_quality = None
    get = replies.get
    frame = get(m.MSP_SONAR_ALTITUDE)
    if frame is not None:
        rng = _decoded(frame, m.Rangefinder.decode)
        if rng is None:
            bad += 1
        elif rng is not _ERROR:
            range_m = rng.distance_m
    frame = get(m.MSP_ATTITUDE)
    if frame is not None:
        att = _decoded(frame, m.Attitude.decode)
        if att is None:
            bad += 1
        elif att is not _ERROR:
            heading, roll, pitch = att.heading_deg, att.roll_deg, att.pitch_deg
    frame = get(m.MSP_RAW_IMU)
    if frame is not None:
        imu = _decoded(frame, m.RawImu.decode)
        if imu is None:
            bad += 1
        elif imu is not _ERROR:
            yaw_rate = float(imu.gyro_dps[2])
    frame = get(m.MSP2_SENSOR_OPTIC_FLOW)
    if frame is not None:
        flow = _decoded(frame, m.OpticFlow.decode)
        if flow is None:
            bad += 1
        elif flow is not _ERROR:
            flow_quality = flow.quality
            if flow.quality > 0:
                flow_x, flow_y = flow.x_rad_s, flow.y_rad_s
    frame = get(m.MSP_ANALOG)
    if frame is not None:
        analog = _decoded(frame, m.Analog.decode)
        if analog is None:
            bad += 1
        elif analog is not _ERROR:
            battery_v = analog.voltage_v
    telemetry = Telemetry(
        t, range_m=range_m, heading_deg=heading, yaw_rate_dps=yaw_rate, roll_deg=roll, pitch_deg=pitch,
        battery_v=battery_v, flow_x_rad_s=flow_x, flow_y_rad_s=flow_y, flow_quality=flow_quality,
    )
    return telemetry, bad


_ERROR: object = object()  # the board answered with an error frame: no value, and not a bad payload


def _decoded(frame: MspFrame, decoder: Callable[[bytes], _M]) -> _M | object | None:
    """The frame's payload decoded; ``_ERROR`` for an error reply, ``None`` for a payload that does not decode."""
    if frame.direction == "!":
        return _ERROR
    try:
        return decoder(frame.payload)
    except m.PayloadError:
        return None
