"""A 4-DOF model of the Feelium blimp (surge, sway, heave, yaw): the physics behind the simulator.

Pure: the caller passes the time step, the motor commands and the air's
velocity, so the controller can be flown faster than real time and
deterministically. Parameters are for the paper's body (323.7 g, ~360 g of
lift, a 64 cm envelope); ``docs/blimp-simulator.md`` says where each number
comes from. Frames: world x north, y east, z up; heading clockwise from
north seen from above; body u forward, v right, w up, r clockwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from feelium.flight.propellers import ONE_DIRECTION_REVERSE_RATIO, REVERSIBLE_3D_REVERSE_RATIO

G = 9.81
AIR_DENSITY = 1.204  # kg/m^3 at 20 degC, sea level
HELIUM_DENSITY = 0.166


@dataclass(frozen=True)
class MotorParams:
    """One motor with its propeller: thrust in newtons at full command, reverse efficiency, lag, deadband.

    ``reverse_ratio`` (reverse thrust / forward thrust) has no default: it is the
    propeller choice (``propellers.py``), and each pair states its own.
    """

    max_thrust_n: float
    reverse_ratio: float
    time_constant_s: float = 0.08
    deadband: float = 0.06

    def static_thrust(self, command: float) -> float:
        """Steady thrust for a command in [-1, 1]: zero inside the deadband, quadratic above it."""
        magnitude = abs(command)
        if magnitude <= self.deadband:
            return 0.0
        fraction = min(1.0, (magnitude - self.deadband) / (1.0 - self.deadband))
        thrust = self.max_thrust_n * fraction * fraction
        return thrust if command > 0 else -thrust * self.reverse_ratio


@dataclass(frozen=True)
class BlimpParams:
    """Mass, buoyancy, drag, geometry and motors of the blimp."""

    body_mass_kg: float = 0.3237
    lift_kg: float = 0.360
    added_mass_ratio: float = 0.5  # of the displaced air, sphere-like body
    frontal_area_m2: float = 0.64 * 0.64
    drag_coefficient: float = 0.8
    linear_drag_n_per_m_s: float = 0.02
    yaw_inertia_kg_m2: float = 0.055
    yaw_linear_drag: float = 0.004  # N m per rad/s
    yaw_quadratic_drag: float = 0.02  # N m per (rad/s)^2
    arm_m: float = 0.25  # lateral offset of each horizontal motor from the centre line
    # Reversible 3D propellers on the horizontal pair (the latency target needs them backward),
    # one-direction propellers on the vertical pair (they mostly push down).
    horizontal_motor: MotorParams = field(
        default_factory=lambda: MotorParams(max_thrust_n=0.25, reverse_ratio=REVERSIBLE_3D_REVERSE_RATIO)
    )
    vertical_motor: MotorParams = field(
        default_factory=lambda: MotorParams(max_thrust_n=0.50, reverse_ratio=ONE_DIRECTION_REVERSE_RATIO)
    )
    floor_m: float = 0.0
    ceiling_m: float = 3.0
    # Added mass differs per axis on a real envelope (gondola, fins): each axis's inertial mass is
    # inertial_mass_kg times its factor. 1.0 everywhere is the sphere-like body.
    surge_mass_factor: float = 1.0
    sway_mass_factor: float = 1.0
    heave_mass_factor: float = 1.0

    @property
    def volume_m3(self) -> float:
        return self.lift_kg / (AIR_DENSITY - HELIUM_DENSITY)

    @property
    def rigid_mass_kg(self) -> float:
        """Body plus the helium it carries: both must be accelerated."""
        return self.body_mass_kg + HELIUM_DENSITY * self.volume_m3

    @property
    def inertial_mass_kg(self) -> float:
        """Rigid mass plus the air dragged along (added mass)."""
        return self.rigid_mass_kg + self.added_mass_ratio * AIR_DENSITY * self.volume_m3

    @property
    def net_buoyancy_n(self) -> float:
        """Upward force left over: positive means it rises when the motors stop."""
        return (self.lift_kg - self.body_mass_kg) * G

    @property
    def quadratic_drag(self) -> float:
        return 0.5 * AIR_DENSITY * self.drag_coefficient * self.frontal_area_m2


@dataclass(frozen=True)
class BlimpState:
    x: float = 0.0
    y: float = 0.0
    z: float = 1.0
    heading_rad: float = 0.0
    u: float = 0.0
    v: float = 0.0
    w: float = 0.0
    r: float = 0.0
    thrust_n: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # after the motor lag

    @property
    def heading_deg(self) -> float:
        return math.degrees(self.heading_rad) % 360.0


MOTOR_NAMES = ("left", "right", "front_vertical", "rear_vertical")


def step(
    params: BlimpParams,
    state: BlimpState,
    commands: tuple[float, float, float, float],
    dt: float,
    wind_world: tuple[float, float, float] = (0.0, 0.0, 0.0),
    external_force_n: tuple[float, float, float] = (0.0, 0.0, 0.0),
    yaw_torque_nm: float = 0.0,
    held: bool = False,
) -> BlimpState:
    """Advance ``dt`` seconds (semi-implicit Euler; keep ``dt`` at or below 10 ms).

    ``commands`` are the four motors in [-1, 1]: left and right push forward
    (+) or back (-); the two vertical motors push the body down (+) or up (-).
    ``held`` models a partner holding the blimp still: motors still spin up,
    but the body does not move.
    """
    motors = (params.horizontal_motor, params.horizontal_motor, params.vertical_motor, params.vertical_motor)
    thrust = tuple(
        t + (motor.static_thrust(min(max(float(c), -1.0), 1.0)) - t) * min(1.0, dt / motor.time_constant_s)
        for t, c, motor in zip(state.thrust_n, commands, motors)
    )
    if held:
        return replace(state, u=0.0, v=0.0, w=0.0, r=0.0, thrust_n=thrust)  # type: ignore[arg-type]
    left, right, front_v, rear_v = thrust
    cos_h, sin_h = math.cos(state.heading_rad), math.sin(state.heading_rad)
    # Air velocity in the body frame.
    wind_u = cos_h * wind_world[0] + sin_h * wind_world[1]
    wind_v = -sin_h * wind_world[0] + cos_h * wind_world[1]
    ext_u = cos_h * external_force_n[0] + sin_h * external_force_n[1]
    ext_v = -sin_h * external_force_n[0] + cos_h * external_force_n[1]
    rel_u, rel_v, rel_w = state.u - wind_u, state.v - wind_v, state.w - wind_world[2]
    k1, k2, mass = params.linear_drag_n_per_m_s, params.quadratic_drag, params.inertial_mass_kg

    def drag(rel: float) -> float:
        return -k1 * rel - k2 * rel * abs(rel)

    du = (left + right + drag(rel_u) + ext_u) / (mass * params.surge_mass_factor) + state.v * state.r
    dv = (drag(rel_v) + ext_v) / (mass * params.sway_mass_factor) - state.u * state.r
    dw = (params.net_buoyancy_n - front_v - rear_v + drag(rel_w) + external_force_n[2]) / (mass * params.heave_mass_factor)
    torque = (left - right) * params.arm_m + yaw_torque_nm
    dr = (torque - params.yaw_linear_drag * state.r - params.yaw_quadratic_drag * state.r * abs(state.r)) / params.yaw_inertia_kg_m2

    u, v, w, r = state.u + du * dt, state.v + dv * dt, state.w + dw * dt, state.r + dr * dt
    x = state.x + (cos_h * u - sin_h * v) * dt
    y = state.y + (sin_h * u + cos_h * v) * dt
    z = state.z + w * dt
    if z <= params.floor_m:
        z, w = params.floor_m, max(0.0, w)
    elif z >= params.ceiling_m:
        z, w = params.ceiling_m, min(0.0, w)
    heading = (state.heading_rad + r * dt) % (2 * math.pi)
    return BlimpState(x, y, z, heading, u, v, w, r, thrust)  # type: ignore[arg-type]


@dataclass(frozen=True)
class DraftParams:
    """Indoor air movement as Ornstein-Uhlenbeck velocities (standard deviation, correlation time)."""

    horizontal_m_s: float = 0.15
    vertical_m_s: float = 0.12
    yaw_torque_nm: float = 0.002
    correlation_s: float = 2.0


class Drafts:
    """Seeded random air velocity that wanders smoothly around zero."""

    def __init__(self, params: DraftParams, seed: int) -> None:
        self.params = params
        self._rng = np.random.default_rng(seed)
        self.wind = np.zeros(3)
        self.torque = 0.0

    def advance(self, dt: float) -> tuple[tuple[float, float, float], float]:
        p = self.params
        decay = math.exp(-dt / p.correlation_s)
        spread = math.sqrt(1.0 - decay * decay)
        sigma = np.array([p.horizontal_m_s, p.horizontal_m_s, p.vertical_m_s])
        self.wind = self.wind * decay + sigma * spread * self._rng.standard_normal(3)
        self.torque = self.torque * decay + p.yaw_torque_nm * spread * float(self._rng.standard_normal())
        return (float(self.wind[0]), float(self.wind[1]), float(self.wind[2])), self.torque
