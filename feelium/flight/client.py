"""The MSP client: requests, replies and the one pipelined exchange a control cycle needs.

It is synchronous on purpose: the service runs it on its one serial thread
with a short read timeout, so the event loop never
blocks, and the same code runs unchanged against pyserial, Betaflight SITL
and the simulated board. A control cycle writes the motor command and all
telemetry requests in one burst and collects the replies until a deadline,
so one 115200-baud cycle costs about one round trip, not six.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable

from feelium.flight import messages as m
from feelium.flight.msp import MspFrame, MspParser, encode_v2
from feelium.flight.telemetry import Telemetry
from feelium.flight.transport import ByteLink


class MspTimeout(TimeoutError):
    """The board did not answer in time."""


class MspErrorReply(RuntimeError):
    """The board answered a request with an error frame (it does not support the command)."""


POLL_COMMANDS = (m.MSP_SONAR_ALTITUDE, m.MSP_ATTITUDE, m.MSP_RAW_IMU, m.MSP2_SENSOR_OPTIC_FLOW)


class MspClient:
    """Talks MSP v2 over a :class:`ByteLink`; counts what went wrong instead of raising mid-flight."""

    def __init__(self, link: ByteLink, timeout_s: float = 0.05, clock: Callable[[], float] = time.monotonic) -> None:
        self.link = link
        self.timeout_s = timeout_s
        self.clock = clock
        self.parser = MspParser()
        self.timeouts = 0
        self.unexpected_replies = 0
        self.error_replies: dict[int, int] = {}
        self.bad_payloads = 0
        self.motor_commands_sent = 0
        self.motor_acks = 0
        self.motor_rejections = 0

    # ---- single requests (probe, conformance tests) ----
    def request(self, command: int, payload: bytes = b"") -> MspFrame:
        """Send one request and return its reply; raises :class:`MspTimeout` or :class:`MspErrorReply`."""
        replies = self.exchange([(command, payload)])
        frame = replies.get(command)
        if frame is None:
            raise MspTimeout(f"no reply to MSP command {command} ({m.COMMAND_NAMES.get(command, '?')}) within {self.timeout_s} s")
        if frame.is_error:
            raise MspErrorReply(f"board rejected MSP command {command} ({m.COMMAND_NAMES.get(command, '?')})")
        return frame

    def api_version(self) -> m.ApiVersion:
        return m.ApiVersion.decode(self.request(m.MSP_API_VERSION).payload)

    def attitude(self) -> m.Attitude:
        return m.Attitude.decode(self.request(m.MSP_ATTITUDE).payload)

    def altitude(self) -> m.Altitude:
        return m.Altitude.decode(self.request(m.MSP_ALTITUDE).payload)

    def rangefinder(self) -> m.Rangefinder:
        return m.Rangefinder.decode(self.request(m.MSP_SONAR_ALTITUDE).payload)

    def raw_imu(self) -> m.RawImu:
        return m.RawImu.decode(self.request(m.MSP_RAW_IMU).payload)

    def analog(self) -> m.Analog:
        return m.Analog.decode(self.request(m.MSP_ANALOG).payload)

    def motors(self) -> tuple[int, ...]:
        return m.decode_motors(self.request(m.MSP_MOTOR).payload)

    def set_motors(self, values_us: Iterable[int]) -> None:
        self.request(m.MSP_SET_MOTOR, m.encode_motors(list(values_us)))

    # ---- the pipelined exchange ----
    def exchange(self, requests: list[tuple[int, bytes]]) -> dict[int, MspFrame]:
        """Write every request at once, then collect replies (by command) until all came or time ran out."""
        self.link.write(b"".join(encode_v2(command, payload) for command, payload in requests))
        wanted = {command for command, _ in requests}
        replies: dict[int, MspFrame] = {}
        deadline = self.clock() + self.timeout_s
        while wanted - replies.keys():
            data = self.link.read(max(1, self.link.in_waiting))
            for frame in self.parser.feed(data):
                if frame.direction == "<":
                    self.unexpected_replies += 1  # our own requests echoed back (e.g. loop://)
                elif frame.command == m.MSP_SET_MOTOR and frame.command not in wanted:
                    if frame.is_error:
                        self.motor_rejections += 1
                    else:
                        self.motor_acks += 1
                elif frame.command in wanted:
                    replies[frame.command] = frame
                    if frame.is_error:
                        self.error_replies[frame.command] = self.error_replies.get(frame.command, 0) + 1
                else:
                    self.unexpected_replies += 1
            if not data and self.clock() >= deadline:
                self.timeouts += 1
                self.parser.abandon()
                break
        return replies

    def send_motors(self, motors_us: Iterable[int]) -> None:
        """Write MSP_SET_MOTOR without waiting: the acknowledgement is consumed by the next poll.

        A control cycle polls, computes, then commands at once, so the motors
        never wait a whole period for a decision already made.
        """
        self.link.write(encode_v2(m.MSP_SET_MOTOR, m.encode_motors(list(motors_us))))
        self.motor_commands_sent += 1

    def send_neutral(self) -> None:
        """Every motor to neutral (no thrust), the safe state; written at once like any motor command."""
        self.send_motors(m.NEUTRAL_MOTORS_US)

    def poll(self, with_battery: bool = False) -> Telemetry:
        """One control cycle's telemetry: rangefinder, attitude, gyro (and the battery when asked)."""
        requests = [(command, b"") for command in POLL_COMMANDS]
        if with_battery:
            requests.append((m.MSP_ANALOG, b""))
        replies = self.exchange(requests)
        return self._telemetry(replies)

    def _telemetry(self, replies: dict[int, MspFrame]) -> Telemetry:
        values: dict[str, object] = {}

        def decoded(command: int, decoder: Callable[[bytes], object]) -> object | None:
            frame = replies.get(command)
            if frame is None or frame.is_error:
                return None
            try:
                return decoder(frame.payload)
            except m.PayloadError:
                self.bad_payloads += 1
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
        return Telemetry(t=self.clock(), **values)  # type: ignore[arg-type]

    def health(self) -> dict[str, object]:
        return {
            **self.parser.counters.as_dict(),
            "timeouts": self.timeouts,
            "unexpected_replies": self.unexpected_replies,
            "error_replies_by_command": dict(self.error_replies),
            "bad_payloads": self.bad_payloads,
            "motor_commands_sent": self.motor_commands_sent,
            "motor_acks": self.motor_acks,
            "motor_rejections": self.motor_rejections,
        }
