"""The MSP commands the motor board must serve, and their payload layouts.

One place defines each layout, used both by the client on the Pi and by the
simulated board, so the two cannot drift apart. The layouts are Betaflight's
(little-endian), which ``docs/motor-board.md`` restates as the contract a
motor board's firmware must meet.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

MSP_API_VERSION = 1
MSP_SONAR_ALTITUDE = 58  # rangefinder: int32 centimetres, negative when out of range
MSP_RAW_IMU = 102
MSP_MOTOR = 104
MSP_ATTITUDE = 108
MSP_ALTITUDE = 109
MSP_ANALOG = 110
MSP_SET_MOTOR = 214
# The optical-flow sensor's reading, relayed by the board. The id and field layout (uint8 quality,
# int32 x, int32 y) are those INAV uses for an MSP optical-flow sensor; the units are this contract's.
MSP2_SENSOR_OPTIC_FLOW = 0x1F02

MOTOR_SLOTS = 8  # MSP_MOTOR / MSP_SET_MOTOR always carry eight values
MOTOR_MIN_US = 1000
MOTOR_NEUTRAL_US = 1500  # reversible motors: 1500 is no thrust, the safe state
NEUTRAL_MOTORS_US = (MOTOR_NEUTRAL_US,) * 4  # the one definition of "motors neutral" (the board's four used slots)
MOTOR_MAX_US = 2000
RANGE_OUT = -1

COMMAND_NAMES = {
    MSP_API_VERSION: "api_version",
    MSP_SONAR_ALTITUDE: "rangefinder",
    MSP_RAW_IMU: "raw_imu",
    MSP_MOTOR: "motor",
    MSP_ATTITUDE: "attitude",
    MSP_ALTITUDE: "altitude",
    MSP_ANALOG: "analog",
    MSP_SET_MOTOR: "set_motor",
    MSP2_SENSOR_OPTIC_FLOW: "optic_flow",
}


class PayloadError(ValueError):
    """A reply's payload is too short for its command's layout."""


def _need(payload: bytes, size: int, what: str) -> None:
    if len(payload) < size:
        raise PayloadError(f"{what} payload needs {size} bytes, got {len(payload)}")


@dataclass(frozen=True)
class ApiVersion:
    protocol: int
    major: int
    minor: int

    def encode(self) -> bytes:
        return struct.pack("<BBB", self.protocol, self.major, self.minor)

    @classmethod
    def decode(cls, payload: bytes) -> "ApiVersion":
        _need(payload, 3, "MSP_API_VERSION")
        return cls(*struct.unpack_from("<BBB", payload))


@dataclass(frozen=True)
class Attitude:
    """Roll and pitch in degrees (sent as tenths), heading in whole degrees 0..359."""

    roll_deg: float
    pitch_deg: float
    heading_deg: float

    def encode(self) -> bytes:
        return struct.pack(
            "<hhh",
            _clamp16(round(self.roll_deg * 10)),
            _clamp16(round(self.pitch_deg * 10)),
            round(self.heading_deg) % 360,
        )

    @classmethod
    def decode(cls, payload: bytes) -> "Attitude":
        _need(payload, 6, "MSP_ATTITUDE")
        roll, pitch, yaw = struct.unpack_from("<hhh", payload)
        return cls(roll / 10.0, pitch / 10.0, float(yaw))


@dataclass(frozen=True)
class Altitude:
    """The board's own altitude estimate (barometer) and vertical speed."""

    altitude_m: float
    vario_m_s: float

    def encode(self) -> bytes:
        return struct.pack("<ih", round(self.altitude_m * 100), _clamp16(round(self.vario_m_s * 100)))

    @classmethod
    def decode(cls, payload: bytes) -> "Altitude":
        _need(payload, 6, "MSP_ALTITUDE")
        cm, vario = struct.unpack_from("<ih", payload)
        return cls(cm / 100.0, vario / 100.0)


@dataclass(frozen=True)
class Rangefinder:
    """Distance to the floor in metres, ``None`` when out of range or failed."""

    distance_m: float | None

    def encode(self) -> bytes:
        cm = RANGE_OUT if self.distance_m is None else round(self.distance_m * 100)
        return struct.pack("<i", cm)

    @classmethod
    def decode(cls, payload: bytes) -> "Rangefinder":
        _need(payload, 4, "MSP_SONAR_ALTITUDE")
        (cm,) = struct.unpack_from("<i", payload)
        return cls(None if cm <= 0 else cm / 100.0)


@dataclass(frozen=True)
class RawImu:
    """Accelerometer (raw units, 512 = 1 g on the simulated board), gyro in deg/s, magnetometer raw."""

    acc: tuple[int, int, int]
    gyro_dps: tuple[int, int, int]
    mag: tuple[int, int, int]

    def encode(self) -> bytes:
        values = [_clamp16(v) for v in (*self.acc, *self.gyro_dps, *self.mag)]
        return struct.pack("<9h", *values)

    @classmethod
    def decode(cls, payload: bytes) -> "RawImu":
        _need(payload, 18, "MSP_RAW_IMU")
        v = struct.unpack_from("<9h", payload)
        return cls(tuple(v[0:3]), tuple(v[3:6]), tuple(v[6:9]))  # type: ignore[arg-type]


@dataclass(frozen=True)
class Analog:
    """Battery: voltage (V), consumed charge (mAh), current (A)."""

    voltage_v: float
    mah_drawn: int
    current_a: float
    rssi: int = 0

    def encode(self) -> bytes:
        return struct.pack(
            "<BHHhH",
            min(255, round(self.voltage_v * 10)),
            min(0xFFFF, self.mah_drawn),
            self.rssi,
            _clamp16(round(self.current_a * 100)),
            min(0xFFFF, round(self.voltage_v * 100)),
        )

    @classmethod
    def decode(cls, payload: bytes) -> "Analog":
        _need(payload, 7, "MSP_ANALOG")
        vbat, mah, rssi, amps = struct.unpack_from("<BHHh", payload)
        voltage = vbat / 10.0
        if len(payload) >= 9:  # Betaflight 4.x appends the voltage in hundredths
            (centi,) = struct.unpack_from("<H", payload, 7)
            voltage = centi / 100.0
        return cls(voltage, mah, amps / 100.0, rssi)


@dataclass(frozen=True)
class OpticFlow:
    """Ground motion seen by a downward flow sensor: angular flow rate in rad/s (sent as mrad/s).

    ``x`` is forward, ``y`` right, in the body frame, already compensated for the body's own
    rotation by the board; the ground speed along an axis is its rate times the height.
    ``quality`` is the sensor's 0..255 confidence, 0 when it has no lock (dark, featureless floor).
    """

    quality: int
    x_rad_s: float
    y_rad_s: float

    def encode(self) -> bytes:
        return struct.pack("<Bii", max(0, min(255, self.quality)), round(self.x_rad_s * 1000), round(self.y_rad_s * 1000))

    @classmethod
    def decode(cls, payload: bytes) -> "OpticFlow":
        _need(payload, 9, "MSP2_SENSOR_OPTIC_FLOW")
        quality, x, y = struct.unpack_from("<Bii", payload)
        return cls(quality, x / 1000.0, y / 1000.0)


def encode_motors(values_us: tuple[int, ...] | list[int]) -> bytes:
    """MSP_SET_MOTOR / MSP_MOTOR payload: eight unsigned 16-bit values, unused slots 0."""
    if len(values_us) > MOTOR_SLOTS:
        raise ValueError(f"at most {MOTOR_SLOTS} motors, got {len(values_us)}")
    padded = list(values_us) + [0] * (MOTOR_SLOTS - len(values_us))
    for value in padded:
        if not 0 <= value <= 0xFFFF:
            raise ValueError(f"motor value {value} does not fit 16 bits")
    return struct.pack(f"<{MOTOR_SLOTS}H", *padded)


def decode_motors(payload: bytes) -> tuple[int, ...]:
    """Motor values from MSP_MOTOR / MSP_SET_MOTOR (any even length up to eight)."""
    if len(payload) % 2:
        raise PayloadError(f"motor payload must have an even length, got {len(payload)}")
    count = min(len(payload) // 2, MOTOR_SLOTS)
    return struct.unpack_from(f"<{count}H", payload)


def _clamp16(value: int) -> int:
    return max(-32768, min(32767, int(value)))
