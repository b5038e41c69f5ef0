"""The fake motor board: speaks the same MSP as the real one, over the blimp model.

It is what ``feelium run --sim`` flies and what the tests fly faster than
real time. It holds the board's half of the contract in
``docs/motor-board.md``: it answers the command subset, applies
``MSP_SET_MOTOR`` and enforces the link watchdog (motors to neutral 300 ms
after the last valid motor command). Its sensors are imperfect on purpose:
rangefinder noise, range limit and dropouts, a gyro bias the board removes
only as well as its start-up calibration can, and drafts.

Time comes from an injected clock: the service passes the daemon's clock,
tests pass a manual one and advance it themselves.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from feelium.flight import blimp_model as bm
from feelium.flight import messages as m
from feelium.flight.msp import MspFrame, MspParser, encode_v2

PHYSICS_DT = 0.005


@dataclass(frozen=True)
class SensorParams:
    """The board's sensors: VL53L1X-class rangefinder, MEMS gyro, 1S battery."""

    range_noise_m: float = 0.008
    range_noise_fraction: float = 0.005
    range_max_m: float = 4.0
    range_dropout_probability: float = 0.02
    range_period_s: float = 0.02
    gyro_noise_dps: float = 0.3
    gyro_bias_dps: float = 0.5
    gyro_calibration_s: float = 1.0
    # Downward optical flow (PMW3901-class, on one module with the rangefinder): the measured
    # horizontal speed. ``flow_fitted = False`` is a board without it (it answers an error reply).
    flow_fitted: bool = True
    flow_noise_rad_s: float = 0.02
    flow_period_s: float = 0.01
    flow_min_height_m: float = 0.08
    flow_max_height_m: float = 4.0
    flow_quality: int = 180
    battery_capacity_mah: float = 600.0
    battery_full_v: float = 4.15
    battery_empty_v: float = 3.3


@dataclass(frozen=True)
class BoardParams:
    blimp: bm.BlimpParams = field(default_factory=bm.BlimpParams)
    sensors: SensorParams = field(default_factory=SensorParams)
    drafts: bm.DraftParams | None = None
    watchdog_s: float = 0.3
    # How long after it arrives a motor command starts to act (UART, the flight code's loop, the ESC's
    # next pulse). 0 is the contract's ideal; a sweep over a physics step shows the controller's margin
    # does not hang on one phase of command against physics (docs/calibrate-flight.md, session 15).
    command_delay_s: float = 0.0
    initial: bm.BlimpState = field(default_factory=bm.BlimpState)


def us_to_command(value_us: int) -> float:
    """A motor value in microseconds to a command in [-1, 1]; 0 (slot unused) is neutral."""
    if value_us == 0:
        return 0.0
    return min(max((value_us - m.MOTOR_NEUTRAL_US) / 500.0, -1.0), 1.0)


class SimMotorBoard:
    """The board: physics, sensors, watchdog and the MSP command handler."""

    def __init__(self, params: BoardParams, seed: int = 1, start_t: float = 0.0) -> None:
        self.params = params
        self.state = params.initial
        self.t = start_t
        self._start_t = start_t
        self._steps = 0  # whole physics steps since start_t: the time is counted, never accumulated (float drift)
        self._pending: list[tuple[float, tuple[int, ...]]] = []  # motor commands not yet acting, by the time they act
        self._rng = np.random.default_rng(seed)
        self._drafts = bm.Drafts(params.drafts, seed + 1) if params.drafts else None
        self.motors_us: tuple[int, ...] = m.NEUTRAL_MOTORS_US
        self._last_motor_t: float | None = None
        self.watchdog_trips = 0
        self._watchdog_tripped = True
        self._gyro_sum = 0.0
        self._gyro_count = 0
        self._gyro_bias_estimate = 0.0
        self._heading_est_deg = self.state.heading_deg
        self._range_m: float | None = self.state.z
        self._next_range_t = start_t
        self._flow = m.OpticFlow(0, 0.0, 0.0)
        self._next_flow_t = start_t
        self._flow_rng = np.random.default_rng(seed + 2)  # its own stream: adding the sensor left the others' draws unchanged
        self.mah_drawn = 0.0
        self.current_a = 0.0
        self.held = False  # a partner holds the body still
        self.external_force_n = (0.0, 0.0, 0.0)
        self.requests = 0

    # ---- physics and sensors ----
    def advance_to(self, t: float) -> None:
        """Integrate up to time ``t`` in fixed physics steps on the grid ``start_t + k * PHYSICS_DT``.

        The grid is counted in whole steps, so a step ending exactly at ``t`` always runs before a command
        that arrives at ``t``: the command acts from its arrival (plus ``command_delay_s``), never a step
        early (an accumulated ``t += PHYSICS_DT`` drifted past its tolerance after 30-90 s and let a third
        of the commands act a step early: docs/calibrate-flight.md, session 15).
        """
        t = round(t, 9)
        while (end := self._grid(self._steps + 1)) <= t:
            self._physics_step(end)
            self._steps += 1
            self.t = end
        while self._pending and self._pending[0][0] <= self.t:
            self.motors_us = self._pending.pop(0)[1]

    def _grid(self, steps: int) -> float:
        return round(self._start_t + steps * PHYSICS_DT, 9)

    def _physics_step(self, end: float) -> None:
        """One physics step from ``self.t`` to ``end``; a command due inside it takes over there.

        The drafts and sensors draw once per whole step whatever the split, so a command delay changes
        only when the command acts, not the noise the flight sees.
        """
        if self._last_motor_t is not None and self.t - self._last_motor_t > self.params.watchdog_s and not self._watchdog_tripped:
            self.motors_us = m.NEUTRAL_MOTORS_US
            self.watchdog_trips += 1
            self._watchdog_tripped = True
        wind, torque = self._drafts.advance(end - self.t) if self._drafts else ((0.0, 0.0, 0.0), 0.0)
        start = self.t
        while True:
            due, motors = self._pending[0] if self._pending and self._pending[0][0] < end else (end, None)
            if due > start:
                commands = tuple(us_to_command(v) for v in self.motors_us[:4])
                self.state = bm.step(
                    self.params.blimp, self.state, commands, due - start, wind, self.external_force_n, torque, self.held  # type: ignore[arg-type]
                )
                self._update_battery(commands, due - start)
                start = due
            if motors is None:
                break
            self._pending.pop(0)
            self.motors_us = motors
        self._update_gyro(end - self.t)
        self._update_range()
        self._update_flow()

    def _gyro_dps(self) -> float:
        s = self.params.sensors
        return math.degrees(self.state.r) + s.gyro_bias_dps + s.gyro_noise_dps * float(self._rng.standard_normal())

    def _update_gyro(self, dt: float) -> None:
        rate = self._gyro_dps()
        if self.t - self._start_t < self.params.sensors.gyro_calibration_s:
            # A board is powered up while someone holds the blimp still, so its start-up
            # calibration sees the gyro's bias and noise, not the body turning in a draft.
            s = self.params.sensors
            self._gyro_sum += s.gyro_bias_dps + s.gyro_noise_dps * float(self._rng.standard_normal())
            self._gyro_count += 1
            self._gyro_bias_estimate = self._gyro_sum / self._gyro_count
            self._heading_est_deg = self.state.heading_deg  # heading is initialised, not integrated, while calibrating
            return
        self._heading_est_deg = (self._heading_est_deg + (rate - self._gyro_bias_estimate) * dt) % 360.0

    def _update_range(self) -> None:
        if self.t < self._next_range_t:
            return
        s = self.params.sensors
        self._next_range_t = round(self.t + s.range_period_s, 9)
        z = self.state.z
        if z > s.range_max_m or self._rng.random() < s.range_dropout_probability:
            self._range_m = None
            return
        sigma = s.range_noise_m + s.range_noise_fraction * z
        self._range_m = max(0.01, z + sigma * float(self._rng.standard_normal()))

    def _update_flow(self) -> None:
        """The flow sensor's latest frame: body-frame ground speed over height, plus noise; no lock out of its range."""
        if self.t < self._next_flow_t:
            return
        s = self.params.sensors
        self._next_flow_t = round(self.t + s.flow_period_s, 9)
        z = self.state.z
        if not s.flow_min_height_m <= z <= s.flow_max_height_m:
            self._flow = m.OpticFlow(0, 0.0, 0.0)
            return
        noise = self._flow_rng.normal(0.0, s.flow_noise_rad_s, 2)
        self._flow = m.OpticFlow(s.flow_quality, self.state.u / z + float(noise[0]), self.state.v / z + float(noise[1]))

    def _update_battery(self, commands: tuple[float, ...], dt: float) -> None:
        self.current_a = 0.12 + sum(0.9 * abs(c) ** 3 for c in commands)
        self.mah_drawn += self.current_a * dt / 3.6

    def battery_v(self) -> float:
        s = self.params.sensors
        remaining = max(0.0, 1.0 - self.mah_drawn / s.battery_capacity_mah)
        return s.battery_empty_v + (s.battery_full_v - s.battery_empty_v) * remaining - 0.05 * self.current_a

    def gyro_yaw_dps(self) -> float:
        """What the board reports on MSP_RAW_IMU: calibrated rate, whole degrees per second."""
        return self._gyro_dps() - self._gyro_bias_estimate

    # ---- MSP ----
    def handle(self, frame: MspFrame) -> bytes:
        """The reply bytes for one request (v2 replies to v2 requests, v1 to v1)."""
        self.requests += 1
        payload = self._reply_payload(frame)
        if payload is None:
            return _encode(frame, b"", "!")
        return _encode(frame, payload, ">")

    def _reply_payload(self, frame: MspFrame) -> bytes | None:
        cmd = frame.command
        if cmd == m.MSP_API_VERSION:
            return m.ApiVersion(0, 1, 46).encode()
        if cmd == m.MSP_SET_MOTOR:
            try:
                values = m.decode_motors(frame.payload)
            except m.PayloadError:
                return None
            if len(values) < 4:
                return None
            motors = tuple(int(min(max(v, m.MOTOR_MIN_US), m.MOTOR_MAX_US)) if v else m.MOTOR_NEUTRAL_US for v in values[:4])
            delay = self.params.command_delay_s
            if delay > 0.0:
                self._pending.append((round(self.t + delay, 9), motors))
            else:
                self.motors_us = motors
            self._last_motor_t = self.t
            self._watchdog_tripped = False
            return b""
        if cmd == m.MSP_MOTOR:
            return m.encode_motors(list(self.motors_us))
        if cmd == m.MSP_ATTITUDE:
            noise = self._rng.normal(0.0, 0.2, 2)
            return m.Attitude(float(noise[0]), float(noise[1]), self._heading_est_deg).encode()
        if cmd == m.MSP_ALTITUDE:
            return m.Altitude(self.state.z + float(self._rng.normal(0.0, 0.1)), self.state.w).encode()
        if cmd == m.MSP_SONAR_ALTITUDE:
            return m.Rangefinder(self._range_m).encode()
        if cmd == m.MSP_RAW_IMU:
            gyro = round(self.gyro_yaw_dps())
            return m.RawImu((0, 0, 512), (0, 0, gyro), (0, 0, 0)).encode()
        if cmd == m.MSP_ANALOG:
            return m.Analog(self.battery_v(), int(self.mah_drawn), self.current_a).encode()
        if cmd == m.MSP2_SENSOR_OPTIC_FLOW and self.params.sensors.flow_fitted:
            return self._flow.encode()
        return None


def _encode(request: MspFrame, payload: bytes, direction: str) -> bytes:
    from feelium.flight.msp import encode_v1

    if request.version == 1 and request.command <= 254:
        return encode_v1(request.command, payload, direction)  # type: ignore[arg-type]
    return encode_v2(request.command, payload, direction)  # type: ignore[arg-type]


class SimSerial:
    """The board seen through a pyserial-like byte link (``write``/``read``/``in_waiting``/``close``).

    Requests are answered when written, after the board has been advanced to
    the clock's time; replies wait in an output buffer. ``connected = False``
    makes every call raise like an unplugged USB adapter.
    """

    def __init__(self, board: SimMotorBoard, clock: Callable[[], float]) -> None:
        self.board = board
        self.clock = clock
        self.connected = True
        self._parser = MspParser()
        self._out = bytearray()
        self.closed = False

    def _check(self) -> None:
        if not self.connected or self.closed:
            raise OSError("simulated motor board disconnected")

    @property
    def in_waiting(self) -> int:
        self._check()
        return len(self._out)

    def write(self, data: bytes) -> int:
        self._check()
        self.board.advance_to(self.clock())
        for frame in self._parser.feed(data):
            if frame.direction == "<":
                self._out += self.board.handle(frame)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        self._check()
        chunk = bytes(self._out[:size])
        del self._out[:size]
        return chunk

    def close(self) -> None:
        self.closed = True


def board_with(params: BoardParams | None = None, **initial: float) -> BoardParams:
    """Board parameters with some initial-state fields replaced (tests and benches)."""
    params = params or BoardParams()
    return replace(params, initial=replace(params.initial, **initial))
