"""The ``[flight]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.flight.propellers import ONE_DIRECTION_REVERSE_RATIO, REVERSIBLE_3D_REVERSE_RATIO
from feelium.settings import section, setting

Axis = Literal["heave", "surge", "yaw"]


@dataclass(frozen=True)
class FlightSimConfig:
    """The simulated motor board flown by `feelium run --sim` (its physics are in docs/blimp-simulator.md)."""

    drafts: bool = setting(True, "Simulate indoor air drafts (random gusts of about 0.15 m/s).")
    start_altitude_m: float = setting(1.2, "Altitude the simulated blimp starts at.", min=0.1, max=3.0)
    rangefinder_dropout: float = setting(0.02, "Probability that one rangefinder reading is missing.", min=0.0, max=1.0)


@dataclass(frozen=True)
class FlightConfig:
    """Motor board link and the closed-loop controller."""

    backend: Literal["auto", "serial", "sim", "off"] = setting(
        "auto", "Motor board: a serial port, the blimp simulator, or off; auto is the serial port on a Raspberry Pi (no board: failed) and sim elsewhere."
    )
    port: str = setting("/dev/ttyAMA0", "Serial device or pyserial URL (socket://host:port, loop://) of the motor board.")
    baudrate: int = setting(115200, "Serial speed of the MSP link.", min=9600, max=2000000)
    rate_hz: float = setting(50.0, "Control loop rate.", min=5.0, max=200.0)
    reply_timeout_s: float = setting(0.03, "How long one control cycle waits for the board's replies.", min=0.005, max=1.0)
    reconnect_min_s: float = setting(0.5, "First delay before reopening a lost serial port (doubles each try).", min=0.05, max=60.0)
    reconnect_max_s: float = setting(0.8, "Longest delay between reopening attempts: under 1 s, so a returning link is used within 1 s.", min=0.1, max=600.0)
    battery_every: int = setting(25, "Poll the battery every N control cycles.", min=1, max=1000)

    # What the controller knows about the body (feed-forward and the mixer).
    net_buoyancy_n: float = setting(0.356, "Upward force with motors off: (360 g lift - 323.7 g body) x g.", min=0.0, max=5.0)
    mass_kg: float = setting(0.59, "Inertial mass: body, helium and added air mass (surge; heave too unless heave_mass_kg is set).", min=0.05, max=10.0)
    heave_mass_kg: float = setting(
        0.0, "Inertial mass in heave when the added air mass differs up and down (calibrate flight fits it); 0: mass_kg.", min=0.0, max=10.0
    )
    yaw_inertia_kg_m2: float = setting(0.055, "Yaw moment of inertia.", min=0.001, max=10.0)
    yaw_drag: float = setting(0.02, "Quadratic yaw drag, N m per (rad/s)^2, for feed-forward and rate prediction.", min=0.0, max=10.0)
    arm_m: float = setting(0.25, "Lateral distance of each horizontal motor from the centre line.", min=0.02, max=2.0)
    horizontal_thrust_n: float = setting(0.25, "Full-command thrust of one horizontal motor.", min=0.01, max=10.0)
    vertical_thrust_n: float = setting(0.5, "Full-command thrust of one vertical motor.", min=0.01, max=10.0)
    horizontal_reverse_ratio: float = setting(
        REVERSIBLE_3D_REVERSE_RATIO,
        "Reverse thrust of a horizontal motor as a fraction of its forward thrust. The spec is reversible 3D"
        " (symmetric-pitch) propellers: one-direction ones (0.6) cannot meet the 100 ms latency backward.",
        min=0.0,
        max=1.0,
    )
    vertical_reverse_ratio: float = setting(
        ONE_DIRECTION_REVERSE_RATIO,
        "Reverse (upward) thrust of a vertical motor as a fraction of its forward (downward) thrust:"
        " one-direction propellers, since their steady job is pushing down against the buoyancy.",
        min=0.0,
        max=1.0,
    )
    motor_deadband: float = setting(0.06, "Command below which a motor makes no thrust.", min=0.0, max=0.5)
    motor_lag_s: float = setting(
        0.08,
        "The motors' first-order lag (time constant) the model assumes: a real one is 40-150 ms;"
        " `feelium calibrate flight` fits it. Stops plan on it times the axis' uncertainty.",
        min=0.01,
        max=0.5,
    )
    quadratic_drag: float = setting(0.197, "Air drag coefficient 0.5 rho Cd A in N/(m/s)^2, for the speed observer.", min=0.0, max=10.0)

    plant_uncertainty: float = setting(
        2.0,
        "How far the real blimp may be from the numbers above: mass, thrust and reverse ratio each within this"
        " factor either way. The loops learn the truth in flight inside that box and count only on what they"
        " have measured (docs/flight-robustness.md). 1 trusts the model: set it only for numbers fitted to this blimp.",
        min=1.0,
        max=4.0,
    )
    # One axis may be known far better than another: a fit pins the surge and yaw ratios within a few percent
    # while the vertical reverse ratio stays loose (short reverse steps, a noisy rangefinder), and one number
    # for all three kept the surge's learned speed cap for the heave's sake.
    heave_uncertainty: float = setting(
        0.0, "plant_uncertainty of the vertical axis alone (thrust per heave mass, its reverse ratio); 0: plant_uncertainty."
        " `feelium calibrate flight` sets it from the fit.", min=0.0, max=4.0
    )
    surge_uncertainty: float = setting(
        0.0, "plant_uncertainty of forward/backward alone (horizontal thrust per surge mass, reverse ratio); 0: plant_uncertainty.",
        min=0.0, max=4.0
    )
    yaw_uncertainty: float = setting(
        0.0, "plant_uncertainty of turns alone (torque per yaw inertia, reverse ratio); 0: plant_uncertainty.", min=0.0, max=4.0
    )
    braking_shown: bool = setting(
        False, "The horizontal reverse thrust above was measured on this blimp: `feelium calibrate flight` sets it when"
        " its flight braked (reverse surge steps). Before the first brake in flight a forward or backward speed is"
        " then capped at what the fitted model, its reverse thrust less one factor surge_uncertainty, can stop from,"
        " not at the box's weakest reverse thrust."
    )
    surge_brake_shown: float = setting(
        0.0, "What the calibration's own reverse surge steps measured of the reverse thrust per surge mass, at its low"
        " end (divided by 1 + 3 x its relative standard error), as a share of the model above (horizontal_thrust_n x"
        " horizontal_reverse_ratio / mass_kg); `feelium calibrate flight` sets it when its flight braked. 0: not measured."
        " Before the first brake in flight the speed cap counts on this share of the modelled brake, and on 0.8 of its"
        " reverse authority instead of 0.55 (docs/calibrate-flight.md, session 20).", min=0.0, max=4.0
    )

    # Gains (accelerations per unit error, so they do not change with mass).
    altitude_kp: float = setting(2.2, "Altitude stiffness, (m/s^2) per m.", min=0.0, max=50.0)
    altitude_kd: float = setting(2.4, "Vertical speed damping, (m/s^2) per m/s.", min=0.0, max=50.0)
    altitude_observer_hz: float = setting(0.6, "Bandwidth of the altitude observer (rangefinder, modelled thrust).", min=0.05, max=10.0)
    disturbance_observer_hz: float = setting(0.06, "Bandwidth of learning the unmodelled vertical force (the integral).", min=0.001, max=5.0)
    altitude_integral_limit: float = setting(
        1.0, "Largest disturbance the observer may learn (the integral), m/s^2: a buoyancy or thrust error inside the box.", min=0.0, max=5.0
    )
    altitude_integral_band_m: float = setting(0.12, "Learn the disturbance only within this altitude error (anti-windup).", min=0.0, max=5.0)
    altitude_error_limit_m: float = setting(0.3, "Altitude error the controller acts on at most (bounded return speed).", min=0.01, max=5.0)
    reference_hz: float = setting(0.4, "Bandwidth of the smooth reference that altitude and heading targets follow.", min=0.05, max=5.0)
    heading_kp: float = setting(3.0, "Heading stiffness, (rad/s^2) per rad.", min=0.0, max=100.0)
    heading_kd: float = setting(3.2, "Yaw rate damping, (rad/s^2) per rad/s.", min=0.0, max=100.0)
    brake_m_s2: float = setting(0.4, "Deceleration planned when forward/backward is released.", min=0.01, max=10.0)
    brake_climb_m_s2: float = setting(0.8, "Deceleration planned when up/down is released.", min=0.01, max=10.0)
    brake_yaw_dps2: float = setting(60.0, "Deceleration of the turn rate planned when a turn is released.", min=1.0, max=1000.0)
    speed_kp: float = setting(5.0, "Forward speed damping, (m/s^2) per m/s.", min=0.0, max=50.0)

    # The six motion commands.
    forward_speed_m_s: float = setting(0.15, "Speed while forward/backward is held.", min=0.0, max=2.0)
    climb_rate_m_s: float = setting(0.25, "Climb rate while up/down is held.", min=0.0, max=2.0)
    yaw_rate_dps: float = setting(20.0, "Turn rate while turn_left/turn_right is held.", min=0.0, max=180.0)
    altitude_min_m: float = setting(0.4, "Lowest altitude a down command may ask for.", min=0.0, max=10.0)
    altitude_max_m: float = setting(2.6, "Highest altitude an up command may ask for.", min=0.0, max=10.0)

    stop_within_s: float = setting(
        1.0, "A stop must leave the body still within this time: rate commands are capped at what it can stop from.", min=0.3, max=10.0
    )
    no_flow_speed_fraction: float = setting(
        0.5, "Without a measured speed (no optical-flow lock) forward/backward run at this fraction of the cap.", min=0.0, max=1.0
    )
    hover_heading_tolerance_deg: float = setting(
        2.0, "In hover the heading loop rests while within this many degrees (the board reports whole degrees).", min=0.0, max=20.0
    )

    # Quietness.
    max_output: float = setting(0.9, "Largest motor command magnitude (fraction of full).", min=0.05, max=1.0)
    slew_per_s: float = setting(25.0, "Largest change of a motor command per second (full range is 2).", min=0.1, max=100.0)

    # Safety.
    soften_factor: float = setting(0.25, "Gain scale while a firm touch or hug is active.", min=0.0, max=1.0)
    soften_hold_s: float = setting(0.8, "Stay soft this long after the last firm touch event.", min=0.0, max=10.0)
    firm_touch_depth: float = setting(0.5, "Relative shadow depth from which a touch counts as firm.", min=0.0, max=1.0)
    range_hold_s: float = setting(0.5, "Hold the last vertical output this long when the rangefinder drops out.", min=0.0, max=10.0)
    telemetry_max_age_s: float = setting(0.1, "Telemetry older than this when it arrives is ignored, never acted on.", min=0.01, max=1.0)
    telemetry_stale_s: float = setting(0.3, "Telemetry older than this is stale: hold, then fail safe.", min=0.02, max=10.0)
    failsafe_buoyancy_fraction: float = setting(
        0.9, "In failsafe the vertical motors cancel this fraction of the net buoyancy: it rises slowly.", min=0.0, max=1.0
    )
    battery_low_v: float = setting(3.5, "Battery voltage reported as low.", min=0.0, max=60.0)
    battery_critical_v: float = setting(3.35, "Battery voltage reported as critical.", min=0.0, max=60.0)

    sim: FlightSimConfig = section(FlightSimConfig)

    def __post_init__(self) -> None:
        # Checked here so `feelium config check` finds it: with the floor above the ceiling every hold is outside one.
        if not self.altitude_min_m < self.altitude_max_m:
            raise ValueError(f"altitude_min_m ({self.altitude_min_m}) must be below altitude_max_m ({self.altitude_max_m})")
        if self.battery_critical_v > self.battery_low_v:
            raise ValueError(f"battery_critical_v ({self.battery_critical_v}) must not be above battery_low_v ({self.battery_low_v})")

    def uncertainty(self, axis: Axis) -> float:
        """How far this axis of the real blimp may be from the config: its own key if set, else ``plant_uncertainty``
        (a value below 1 counts as 1: nothing is known better than exactly)."""
        own = {"heave": self.heave_uncertainty, "surge": self.surge_uncertainty, "yaw": self.yaw_uncertainty}[axis]
        return max(own, 1.0) if own else self.plant_uncertainty

    def within_altitude_limits(self, z: float) -> bool:
        """Whether altitude ``z`` is inside [``altitude_min_m``, ``altitude_max_m``]."""
        return self.altitude_min_m <= z <= self.altitude_max_m

    @property
    def heave_mass(self) -> float:
        """The mass the altitude loop and observer accelerate: the fitted heave mass, else ``mass_kg``."""
        return self.heave_mass_kg or self.mass_kg
