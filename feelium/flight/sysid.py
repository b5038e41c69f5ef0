"""System identification of the blimp's flight plant from a logged flight: the pure core of `calibrate flight`.

Fed arrays (the control ticks, the four motor commands sent at each tick and
held until the next, and the board's rangefinder, gyro and optical-flow
readings), it fits the model ``blimp_model.py`` simulates and the controller
assumes, per axis:

    m a = thrust(commands) + known force - c1 v - c2 v|v|

where a motor's thrust is zero within its deadband, grows with the square of
the command beyond it up to ``max_thrust`` at full command (times the reverse
ratio below 1500 us), and follows the command through a first-order lag.

Method (``docs/calibrate-flight.md``): equation error on rates. Each measured
rate (climb rate from the rangefinder's altitude, forward speed from flow x
height, yaw rate from the gyro) is smoothed with a zero-phase Gaussian and
differentiated; every regressor is smoothed by the same kernel, so the filter
cancels on both sides. For a given lag and deadband the model is linear in
its unknowns and is solved by least squares; lag and deadband, the nonlinear
two, are found by a coordinate search on the residual. Standard errors come
from the residual and the normal matrix, inflated for the residual's
correlation (the smoothing makes neighbouring samples dependent).

Identifiability: without a force sensor only ratios (thrust / mass, drag /
mass) are observable. Two known things give them a scale: the weighed net
buoyancy (heave: mass, vertical thrust in newtons) and the body's drag, which
the model takes as the same on every translational axis (a near-spherical
envelope). Surge, through the clean flow sensor, gives the drag's shape per
surge mass; heave fitted with that shape gives the ratio of the two masses;
the surge mass, horizontal thrust, drags and (through the measured arm) yaw
inertia follow. That ratio is the weak link (the heave drag is small against
the thrust); the ratios the controller uses do not depend on it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

LAG_RANGE_S = (0.02, 0.25)
DEADBAND_RANGE = (0.0, 0.3)
# Gaussian sigma per measured rate, set by the sensor's noise: the rangefinder's altitude (1-2 cm a
# reading) is differentiated twice, the flow speed (about 3 cm/s a frame) and the gyro (0.3 deg/s plus
# whole-degree steps) once. Wider loses the lag's detail, narrower drowns the fit in noise.
SMOOTH_S = {"heave": 0.2, "surge": 0.12, "yaw": 0.07}
# A measurement's age when the Pi gets it: the fit compares each reading with the body at that age. A flow
# frame every 10 ms is about 5 ms old, the gyro is read at the request. The rangefinder's age matters most
# (the heave drag, small against the thrust, trades against it: 5 ms is 6 % of the mass ratio) and depends
# on the sensor's timing, so it is fitted, within this range.
RANGE_LATENCY_RANGE_S = (0.0, 0.04)
FLOW_LATENCY_S = 0.005
NEAR_LIMIT_M = 0.12  # samples this close to the floor/ceiling limits are dropped (contact, ground effect)


@dataclass(frozen=True)
class FlightRecord:
    """One logged flight, sampled at the control ticks; NaN marks a missing reading.

    ``commands[k]`` (N x 4, each in [-1, 1]: left, right, front vertical, rear
    vertical) is what was sent at ``t[k]`` and held until ``t[k + 1]``.
    """

    t: np.ndarray
    commands: np.ndarray
    range_m: np.ndarray
    yaw_rate_dps: np.ndarray
    flow_x_rad_s: np.ndarray


@dataclass(frozen=True)
class Estimate:
    """One fitted value with its standard error."""

    value: float
    stderr: float

    @property
    def relative(self) -> float:
        return abs(self.stderr / self.value) if self.value else math.inf


@dataclass
class AxisFit:
    """The linear least squares of one axis at the chosen lag and deadband."""

    names: tuple[str, ...]
    coef: np.ndarray
    cov: np.ndarray
    residual_rms: float  # of the rate derivative, in the axis's units per second
    rate_rms: float  # of the rate derivative itself, for scale
    samples: int

    def estimate(self, name: str) -> Estimate:
        i = self.names.index(name)
        return Estimate(float(self.coef[i]), float(math.sqrt(max(self.cov[i, i], 0.0))))


@dataclass
class PlantFit:
    """The fitted plant in physical units, what the controller's config needs, and how well it fits."""

    values: dict[str, Estimate] = field(default_factory=dict)
    residuals: dict[str, dict[str, float]] = field(default_factory=dict)

    def value(self, name: str) -> float:
        return self.values[name].value


# ---------------------------------------------------------------- signal helpers
def _gaussian_kernel(sigma_samples: float) -> np.ndarray:
    half = max(1, int(math.ceil(3.0 * sigma_samples)))
    x = np.arange(-half, half + 1, dtype=float)
    kernel = np.exp(-0.5 * (x / sigma_samples) ** 2)
    return kernel / kernel.sum()


def smooth(values: np.ndarray, sigma_samples: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-phase Gaussian smoothing that skips NaNs; returns the smoothed values and whether each is trusted
    (at least 90 % of the kernel's weight fell on real samples)."""
    kernel = _gaussian_kernel(sigma_samples)
    valid = np.isfinite(values)
    filled = np.where(valid, values, 0.0)
    weight = np.convolve(valid.astype(float), kernel, mode="same")
    total = np.convolve(filled, kernel, mode="same")
    with np.errstate(invalid="ignore", divide="ignore"):
        out = total / weight
    return out, weight >= 0.9


def motor_shape(commands: np.ndarray, deadband: float) -> tuple[np.ndarray, np.ndarray]:
    """Thrust per full thrust of each command, split by direction: (forward part >= 0, reverse part >= 0)."""
    magnitude = np.clip((np.abs(commands) - deadband) / (1.0 - deadband), 0.0, 1.0) ** 2
    return np.where(commands > 0, magnitude, 0.0), np.where(commands < 0, magnitude, 0.0)


def lagged_mean(steady: np.ndarray, lag_s: float, dt: float) -> np.ndarray:
    """Mean over each control period of a first-order lag driven by ``steady`` held over that period.

    Exact for a zero-order hold: the motor starts period k at T_k and relaxes toward S_k.
    """
    decay = math.exp(-dt / lag_s)
    taps = max(2, int(math.ceil(14.0 * lag_s / dt)))  # the tail left off is under 1e-6
    kernel = (1.0 - decay) * decay ** np.arange(taps)
    start = np.concatenate(([0.0], np.convolve(steady, kernel)[: steady.size - 1]))  # T_k
    return steady + (start - steady) * lag_s / dt * (1.0 - decay)


def _on_grid(record: FlightRecord, values: np.ndarray, latency_s: float, grid: np.ndarray) -> np.ndarray:
    """Readings placed at the time they describe (``t - latency``) and interpolated onto the grid; NaN where a
    gap is longer than two periods."""
    t = record.t - latency_s
    valid = np.isfinite(values)
    if valid.sum() < 2:
        return np.full(grid.size, np.nan)
    tv, vv = t[valid], values[valid]
    out = np.interp(grid, tv, vv)
    idx = np.clip(np.searchsorted(tv, grid), 1, tv.size - 1)
    gap = tv[idx] - tv[idx - 1]
    dt = float(np.median(np.diff(record.t)))
    out[(gap > 2.5 * dt) | (grid < tv[0]) | (grid > tv[-1])] = np.nan
    return out


@dataclass(frozen=True)
class Signals:
    """The record on a uniform grid: rates at the period mid-points, their derivative, the commands."""

    dt: float
    commands: np.ndarray  # N x 4, held over [t_k, t_k+1)
    rate: dict[str, np.ndarray]  # at the mid-points t_k + dt/2, length N - 1: heave m/s, surge m/s, yaw rad/s
    accel: dict[str, np.ndarray]  # d rate / dt over each period, length N - 1
    trusted: dict[str, np.ndarray]
    sigma: dict[str, float]  # smoothing in samples, applied to the regressors as well
    measured: dict[str, np.ndarray]  # the raw readings at the ticks t_k, length N: altitude m, forward speed m/s, yaw rate rad/s
    inside_heave: np.ndarray  # per tick: the altitude is clear of the floor and ceiling limits


def prepare(record: FlightRecord, floor_limit_m: float = 0.0, ceiling_limit_m: float = math.inf,
            range_latency_s: float = 0.01) -> Signals:
    """Resample, smooth and differentiate the three measured rates."""
    t = np.asarray(record.t, float)
    dt = float(np.median(np.diff(t)))
    grid = t[0] + dt * np.arange(t.size)
    # The command held at each grid point is the nearest tick's: the grid and the logged ticks are the same
    # instants up to rounding (``t`` accumulates a float period), and a grid point a hair before its tick must
    # not take the previous tick's command (that delayed every command one period in the last minutes of a flight).
    held = np.clip(np.searchsorted(t, grid + 0.5 * dt, side="right") - 1, 0, t.size - 1)
    commands = np.asarray(record.commands, float)[held]
    rate: dict[str, np.ndarray] = {}
    accel: dict[str, np.ndarray] = {}
    trusted: dict[str, np.ndarray] = {}
    sigma: dict[str, float] = {}

    z_raw = _on_grid(record, np.asarray(record.range_m, float), range_latency_s, grid)
    sigma["heave"] = SMOOTH_S["heave"] / dt
    z, ok = smooth(z_raw, sigma["heave"])
    w = np.gradient(z, dt)
    mid_w = 0.5 * (w[1:] + w[:-1])
    rate["heave"], accel["heave"] = mid_w, np.diff(w) / dt
    clear = (z > floor_limit_m + NEAR_LIMIT_M) & (z < ceiling_limit_m - NEAR_LIMIT_M)
    trusted["heave"] = ok[1:] & ok[:-1] & clear[1:] & np.isfinite(mid_w)

    height = np.interp(grid, grid[np.isfinite(z)], z[np.isfinite(z)]) if np.isfinite(z).any() else np.full(grid.size, np.nan)
    flow_u = _on_grid(record, np.asarray(record.flow_x_rad_s, float), FLOW_LATENCY_S, grid) * height
    gyro = np.radians(_on_grid(record, np.asarray(record.yaw_rate_dps, float), 0.0, grid))
    for axis, raw in (("surge", flow_u), ("yaw", gyro)):
        sigma[axis] = SMOOTH_S[axis] / dt
        value, ok = smooth(raw, sigma[axis])
        rate[axis] = 0.5 * (value[1:] + value[:-1])
        accel[axis] = np.diff(value) / dt
        trusted[axis] = ok[1:] & ok[:-1] & np.isfinite(rate[axis])
    measured = {"heave": z_raw, "surge": flow_u, "yaw": gyro}
    return Signals(dt, commands, rate, accel, trusted, sigma, measured, clear)


# ---------------------------------------------------------------- least squares
def least_squares(columns: dict[str, np.ndarray], target: np.ndarray, mask: np.ndarray, sigma_samples: float) -> AxisFit:
    """Ordinary least squares on the trusted samples, with standard errors for a smoothed (correlated) residual.

    The Gaussian smoothing leaves about ``2 sqrt(pi) sigma`` samples per independent one, so the
    covariance is scaled by that factor.
    """
    names = tuple(columns)
    x = np.stack([columns[n][mask] for n in names], axis=1)
    y = target[mask]
    scale = np.maximum(np.sqrt(np.mean(x * x, axis=0)), 1e-12)
    coef_scaled, *_ = np.linalg.lstsq(x / scale, y, rcond=None)
    coef = coef_scaled / scale
    residual = y - x @ coef
    dof = max(1, y.size - len(names))
    variance = float(residual @ residual) / dof
    normal = (x / scale).T @ (x / scale)
    inflation = 2.0 * math.sqrt(math.pi) * sigma_samples
    cov = np.linalg.pinv(normal) * variance * inflation / np.outer(scale, scale)
    return AxisFit(names, coef, cov, math.sqrt(variance), float(np.sqrt(np.mean(y * y))), int(y.size))


def _smoothed(values: np.ndarray, sigma: float) -> np.ndarray:
    return smooth(values, sigma)[0]


def _pair_columns(sig: Signals, motors: Sequence[int], lag_s: float, deadband: float, axis: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per motor: its lagged forward and reverse thrust shapes, period means, smoothed like the rates."""
    out = []
    for i in motors:
        fwd, rev = motor_shape(sig.commands[:, i], deadband)
        fwd_l = _smoothed(lagged_mean(fwd, lag_s, sig.dt), sig.sigma[axis])[:-1]
        rev_l = _smoothed(lagged_mean(rev, lag_s, sig.dt), sig.sigma[axis])[:-1]
        out.append((fwd_l, rev_l))
    return out


def heave_fit(sig: Signals, lag_s: float, deadband: float) -> AxisFit:
    """Up acceleration = B/m - Tv/m (down pushes) + Tv rv/m (up pushes) - c1/m w - c2/m w|w|."""
    (f3, r3), (f4, r4) = _pair_columns(sig, (2, 3), lag_s, deadband, "heave")
    w = sig.rate["heave"]
    columns = {"buoyancy_per_mass": np.ones_like(w), "thrust_per_mass": -(f3 + f4), "reverse_thrust_per_mass": r3 + r4,
               "linear_drag_per_mass": -w, "quadratic_drag_per_mass": -w * np.abs(w)}
    return least_squares(columns, sig.accel["heave"], sig.trusted["heave"], sig.sigma["heave"])


def surge_fit(sig: Signals, lag_s: float, deadband: float) -> AxisFit:
    """Forward acceleration = Th/m (pushes) - Th rh/m (reverse pushes) - c1/m u - c2/m u|u|."""
    (f1, r1), (f2, r2) = _pair_columns(sig, (0, 1), lag_s, deadband, "surge")
    u = sig.rate["surge"]
    columns = {"thrust_per_mass": f1 + f2, "reverse_thrust_per_mass": -(r1 + r2),
               "linear_drag_per_mass": -u, "quadratic_drag_per_mass": -u * np.abs(u)}
    return least_squares(columns, sig.accel["surge"], sig.trusted["surge"], sig.sigma["surge"])


def yaw_fit(sig: Signals, lag_s: float, deadband: float) -> AxisFit:
    """Yaw acceleration = Th arm/I (left - right forward) - Th rh arm/I (left - right reverse) - d1/I r - d2/I r|r|."""
    (f1, r1), (f2, r2) = _pair_columns(sig, (0, 1), lag_s, deadband, "yaw")
    r = sig.rate["yaw"]
    columns = {"torque_per_inertia": f1 - f2, "reverse_torque_per_inertia": -(r1 - r2),
               "linear_drag_per_inertia": -r, "quadratic_drag_per_inertia": -r * np.abs(r)}
    return least_squares(columns, sig.accel["yaw"], sig.trusted["yaw"], sig.sigma["yaw"])


def _relative_sse(fit: AxisFit) -> float:
    return (fit.residual_rms / max(fit.rate_rms, 1e-12)) ** 2


def search_lag_deadband(cost: Callable[[float, float], float], rounds: int = 3) -> tuple[float, float]:
    """Minimise ``cost(lag, deadband)``: a coarse grid, then alternating golden-section searches around its best."""
    lags = np.geomspace(*LAG_RANGE_S, 9)
    bands = np.linspace(*DEADBAND_RANGE, 7)
    best = min(((cost(float(lag), float(band)), float(lag), float(band)) for lag in lags for band in bands))
    _, lag, band = best
    lag_step, band_step = lags[1] / lags[0], bands[1] - bands[0]
    for _ in range(rounds):
        lag = _golden(lambda x: cost(x, band), max(LAG_RANGE_S[0], lag / lag_step), min(LAG_RANGE_S[1], lag * lag_step))
        band = _golden(lambda x: cost(lag, x), max(DEADBAND_RANGE[0], band - band_step), min(DEADBAND_RANGE[1], band + band_step))
        lag_step, band_step = math.sqrt(lag_step), band_step / 2.0
    return lag, band


def _golden(f: Callable[[float], float], lo: float, hi: float, iterations: int = 14) -> float:
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo + (1 - ratio) * (hi - lo), lo + ratio * (hi - lo)
    fa, fb = f(a), f(b)
    for _ in range(iterations):
        if fa <= fb:
            hi, b, fb = b, a, fa
            a = lo + (1 - ratio) * (hi - lo)
            fa = f(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + ratio * (hi - lo)
            fb = f(b)
    return a if fa <= fb else b


# ---------------------------------------------------------------- the plant
def _ratio(num: Estimate, den: Estimate) -> Estimate:
    value = num.value / den.value
    return Estimate(value, abs(value) * math.hypot(num.relative, den.relative))


def _product(a: Estimate, b: Estimate) -> Estimate:
    value = a.value * b.value
    return Estimate(value, abs(value) * math.hypot(a.relative, b.relative))


def _scaled(a: Estimate, factor: float) -> Estimate:
    return Estimate(a.value * factor, abs(a.stderr * factor))


@dataclass(frozen=True)
class AxisFits:
    """The three axis fits at their chosen lags and deadbands (the plots replay them)."""

    heave: AxisFit
    surge: AxisFit
    yaw: AxisFit
    lag_s: float
    vertical_deadband: float
    horizontal_deadband: float
    scaled_heave: AxisFit  # heave with surge's drag shape: the heave values and the mass ratio


def fit_axes(sig: Signals) -> AxisFits:
    """The motor lag and the horizontal deadband from surge and yaw together (the flow and the gyro are the
    sharpest sensors, and the four motors are one type), the vertical deadband from heave at that lag, then
    heave once more with the drag's shape taken from surge (``scaled_heave_fit``)."""

    def horizontal_cost(lag: float, band: float) -> float:
        return _relative_sse(surge_fit(sig, lag, band)) + _relative_sse(yaw_fit(sig, lag, band))

    lag, h_band = search_lag_deadband(horizontal_cost)
    bands = np.linspace(*DEADBAND_RANGE, 13)
    coarse = float(bands[int(np.argmin([_relative_sse(heave_fit(sig, lag, float(b))) for b in bands]))])
    step = float(bands[1] - bands[0])
    v_band = _golden(lambda b: _relative_sse(heave_fit(sig, lag, b)), max(0.0, coarse - step), coarse + step)
    surge = surge_fit(sig, lag, h_band)
    scaled = scaled_heave_fit(sig, lag, v_band, _drag_per_surge_mass(surge))
    return AxisFits(heave_fit(sig, lag, v_band), surge, yaw_fit(sig, lag, h_band), lag, v_band, h_band, scaled)


def scaled_heave_fit(sig: Signals, lag_s: float, deadband: float, drag_per_surge_mass: Callable[[np.ndarray], np.ndarray]) -> AxisFit:
    """Heave with one drag for the body: up acceleration = B/m - Tv/m pushes + Tv rv/m pushes - (ms/mh) D(w)/ms,
    where D/ms is surge's fitted drag per surge mass. The drag is small against the thrust in heave and the
    rangefinder is noisy, so heave alone gets its shape wrong; surge sees it cleanly but per an unknown
    mass. Here surge gives the shape and heave, whose scale the weighed buoyancy fixes, the mass ratio."""
    (f3, r3), (f4, r4) = _pair_columns(sig, (2, 3), lag_s, deadband, "heave")
    w = sig.rate["heave"]
    columns = {"buoyancy_per_mass": np.ones_like(w), "thrust_per_mass": -(f3 + f4), "reverse_thrust_per_mass": r3 + r4,
               "surge_per_heave_mass": -drag_per_surge_mass(w)}
    return least_squares(columns, sig.accel["heave"], sig.trusted["heave"], sig.sigma["heave"])


def _drag_per_surge_mass(surge: AxisFit) -> Callable[[np.ndarray], np.ndarray]:
    c1, c2 = surge.estimate("linear_drag_per_mass").value, surge.estimate("quadratic_drag_per_mass").value

    def drag(v: np.ndarray) -> np.ndarray:
        return c1 * v + c2 * v * np.abs(v)

    return drag


def identify(record: FlightRecord, net_buoyancy_n: float, arm_m: float,
             floor_limit_m: float = 0.0, ceiling_limit_m: float = math.inf,
             stand_thrust_n: Estimate | None = None) -> tuple[PlantFit, AxisFits, Signals]:
    """The plant in physical units from one logged flight; ``net_buoyancy_n`` (weighed) and ``arm_m`` (measured)
    give the scale.

    ``stand_thrust_n``, one horizontal motor's full forward thrust read on a thrust stand (docs/motor-board.md's
    acceptance test), scales the horizontal values directly: the surge mass is then that thrust over the fitted
    thrust per mass. Without it the scale comes through the heave drag, which the drafts blur (docs/calibrate-flight.md,
    session 26: the surge mass within 10 % on 8 of 20 plants through the heave, 18 of 20 from an exact stand figure and
    12 of 20 from one 5 % high)."""
    sig = prepare(record, floor_limit_m, ceiling_limit_m)
    fits = fit_axes(sig)
    drag_shape = _drag_per_surge_mass(fits.surge)

    def latency_cost(latency: float) -> float:
        at = prepare(record, floor_limit_m, ceiling_limit_m, latency)
        return _relative_sse(scaled_heave_fit(at, fits.lag_s, fits.vertical_deadband, drag_shape))

    latency = _golden(latency_cost, *RANGE_LATENCY_RANGE_S, iterations=12)
    sig = prepare(record, floor_limit_m, ceiling_limit_m, latency)
    fits = fit_axes(sig)
    heave, surge, yaw = fits.scaled_heave, fits.surge, fits.yaw
    b_per_m = heave.estimate("buoyancy_per_mass")
    heave_mass = Estimate(net_buoyancy_n / b_per_m.value, net_buoyancy_n / b_per_m.value * b_per_m.relative)
    values: dict[str, Estimate] = {"heave_mass_kg": heave_mass}
    values["vertical_thrust_n"] = _scaled(_ratio(heave.estimate("thrust_per_mass"), b_per_m), net_buoyancy_n)  # per motor
    values["vertical_reverse_ratio"] = _ratio(heave.estimate("reverse_thrust_per_mass"), heave.estimate("thrust_per_mass"))
    thrust_per_mass = surge.estimate("thrust_per_mass")
    if stand_thrust_n is None:
        surge_mass = _product(heave_mass, heave.estimate("surge_per_heave_mass"))
        horizontal_thrust = _product(thrust_per_mass, surge_mass)
    else:
        surge_mass, horizontal_thrust = _ratio(stand_thrust_n, thrust_per_mass), stand_thrust_n
    values["surge_mass_kg"] = surge_mass
    values["linear_drag_n_per_m_s"] = _product(surge.estimate("linear_drag_per_mass"), surge_mass)
    values["quadratic_drag"] = _product(surge.estimate("quadratic_drag_per_mass"), surge_mass)
    values["horizontal_thrust_n"] = horizontal_thrust  # per motor
    reverse_surge = _ratio(surge.estimate("reverse_thrust_per_mass"), thrust_per_mass)
    reverse_yaw = _ratio(yaw.estimate("reverse_torque_per_inertia"), yaw.estimate("torque_per_inertia"))
    values["horizontal_reverse_ratio"] = _inverse_variance_mean(reverse_surge, reverse_yaw)

    torque_per_inertia = yaw.estimate("torque_per_inertia")
    inertia = _ratio(_scaled(values["horizontal_thrust_n"], arm_m), torque_per_inertia)
    values["yaw_inertia_kg_m2"] = inertia
    values["yaw_linear_drag"] = _product(yaw.estimate("linear_drag_per_inertia"), inertia)
    values["yaw_quadratic_drag"] = _product(yaw.estimate("quadratic_drag_per_inertia"), inertia)
    # The ratios the controller's dynamics depend on: every surge and yaw value above scales with the surge
    # mass (poorly determined through the heave drag, better from a thrust stand's figure), these do not.
    values["surge_thrust_per_mass"] = thrust_per_mass
    values["surge_reverse_thrust_per_mass"] = surge.estimate("reverse_thrust_per_mass")  # what a brake decelerates by
    values["yaw_torque_per_inertia"] = torque_per_inertia
    values["heave_thrust_per_mass"] = heave.estimate("thrust_per_mass")
    values["motor_lag_s"] = Estimate(fits.lag_s, _curvature_stderr(sig, fits, "motor_lag_s"))
    values["range_latency_s"] = Estimate(latency, math.nan)
    for name in ("vertical_deadband", "horizontal_deadband"):
        values[name] = Estimate(getattr(fits, name), _curvature_stderr(sig, fits, name))
    residuals = {axis: {"residual_rms": fit.residual_rms, "relative_residual": fit.residual_rms / max(fit.rate_rms, 1e-12),
                        "samples": float(fit.samples)}
                 for axis, fit in (("heave", fits.heave), ("surge", surge), ("yaw", yaw))}
    return PlantFit(values, residuals), fits, sig


def _inverse_variance_mean(a: Estimate, b: Estimate) -> Estimate:
    wa, wb = 1.0 / max(a.stderr, 1e-12) ** 2, 1.0 / max(b.stderr, 1e-12) ** 2
    return Estimate((a.value * wa + b.value * wb) / (wa + wb), 1.0 / math.sqrt(wa + wb))


def _curvature_stderr(sig: Signals, fits: AxisFits, name: str) -> float:
    """Standard error of a searched parameter (lag or deadband) from the residual's curvature at its minimum.

    The sum of squares grows by about one residual variance per independent sample when the parameter
    moves one standard error: se = sqrt(2 s^2 k / S''), with k samples per independent one (the smoothing).
    """
    vertical = name == "vertical_deadband"
    base = fits.heave if vertical else fits.surge

    def at(x: float) -> float:
        if name == "motor_lag_s":
            fit = surge_fit(sig, x, fits.horizontal_deadband)
        else:
            fit = heave_fit(sig, fits.lag_s, x) if vertical else surge_fit(sig, fits.lag_s, x)
        return fit.residual_rms**2 * fit.samples

    x0 = fits.lag_s if name == "motor_lag_s" else (fits.vertical_deadband if vertical else fits.horizontal_deadband)
    step = 0.1 * x0 if name == "motor_lag_s" else 0.01
    centre = max(x0, step)
    curvature = (at(centre + step) - 2.0 * at(centre) + at(centre - step)) / step**2
    per_independent = 2.0 * math.sqrt(math.pi) * sig.sigma["heave" if vertical else "surge"]
    if curvature <= 0:
        return math.inf
    return math.sqrt(2.0 * base.residual_rms**2 * per_independent / curvature)


def predict_rates(sig: Signals, fits: AxisFits, axis: str, start: int, stop: int) -> np.ndarray:
    """The fitted model's rate over periods ``start..stop``, started from the measured rate and driven by the
    commands alone (a free-run, not one-step-ahead: what the plots compare with the measurement)."""
    if axis == "heave":
        fit, motors, band = fits.scaled_heave, (2, 3), fits.vertical_deadband
    else:
        fit, motors, band = (fits.surge if axis == "surge" else fits.yaw), (0, 1), fits.horizontal_deadband
    shapes = [tuple(lagged_mean(s, fits.lag_s, sig.dt) for s in motor_shape(sig.commands[:, i], band)) for i in motors]
    (f_a, r_a), (f_b, r_b) = shapes
    c = dict(zip(fit.names, fit.coef))
    surge_drag = _drag_per_surge_mass(fits.surge)
    rates = np.empty(stop - start)
    v = float(np.nan_to_num(sig.rate[axis][start]))
    for j, k in enumerate(range(start, stop)):
        rates[j] = v
        if axis == "heave":
            a = (c["buoyancy_per_mass"] - c["thrust_per_mass"] * (f_a[k] + f_b[k]) + c["reverse_thrust_per_mass"] * (r_a[k] + r_b[k])
                 - c["surge_per_heave_mass"] * float(surge_drag(np.asarray(v))))
        elif axis == "surge":
            a = (c["thrust_per_mass"] * (f_a[k] + f_b[k]) - c["reverse_thrust_per_mass"] * (r_a[k] + r_b[k])
                 - c["linear_drag_per_mass"] * v - c["quadratic_drag_per_mass"] * v * abs(v))
        else:
            a = (c["torque_per_inertia"] * (f_a[k] - f_b[k]) - c["reverse_torque_per_inertia"] * (r_a[k] - r_b[k])
                 - c["linear_drag_per_inertia"] * v - c["quadratic_drag_per_inertia"] * v * abs(v))
        v += a * sig.dt
    return rates
