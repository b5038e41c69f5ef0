"""Telemetry from one burst's replies: each decoded, a bad payload counted and left out, never raised."""

from __future__ import annotations

from collections.abc import Callable

from feelium.flight import messages as m
from feelium.flight.msp import MspFrame
from feelium.flight.telemetry import Telemetry


def decode_telemetry(replies: dict[int, MspFrame], t: float) -> tuple[Telemetry, int]:
    """The telemetry the replies carry, stamped ``t``, and how many payloads could not be decoded."""
    values: dict[str, object] = {}
    bad = 0

    def decoded(command: int, decoder: Callable[[bytes], object]) -> object | None:
        nonlocal bad
        frame = replies.get(command)
        if frame is None or frame.is_error:
            return None
        try:
            return decoder(frame.payload)
        except m.PayloadError:
            bad += 1
            return None

    rng = decoded(m.MSP_SONAR_ALTITUDE, m.Rangefinder.decode)
    if isinstance(rng, m.Rangefinder):
        values["range_m"] = rng.distance_m
    att = decoded(m.MSP_ATTITUDE, m.Attitude.decode)
    if isinstance(att, m.Attitude):
        values.update(heading_deg=att.heading_deg, roll_deg=att.roll_deg, pitch_deg=att.pitch_deg)
    imu = decoded(m.MSP_RAW_IMU, m.RawImu.decode)
    if isinstance(imu, m.RawImu):
        values["yaw_rate_dps"] = float(imu.gyro_dps[2])
    flow = decoded(m.MSP2_SENSOR_OPTIC_FLOW, m.OpticFlow.decode)
    if isinstance(flow, m.OpticFlow):
        values["flow_quality"] = flow.quality
        if flow.quality > 0:
            values.update(flow_x_rad_s=flow.x_rad_s, flow_y_rad_s=flow.y_rad_s)
    analog = decoded(m.MSP_ANALOG, m.Analog.decode)
    if isinstance(analog, m.Analog):
        values["battery_v"] = analog.voltage_v
    return Telemetry(t=t, **values), bad  # type: ignore[arg-type]
