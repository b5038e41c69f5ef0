"""The heave output-error refinement (`feelium/lab/flight/heave_output_error.py`) on synthetic data: exact where the model is."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feelium.flight.sysid import AxisFit, Signals
from feelium.lab.flight.heave_output_error import (HEAVE_NAMES, Group, Problem, Windows, correlation_length, levenberg_marquardt,
                                         refine_heave, simulate_heave)


@settings(max_examples=20, deadline=None)
@given(rate=st.floats(0.3, 3.0), amplitude=st.floats(0.5, 2.0), seed=st.integers(0, 2**16))
def test_levenberg_marquardt_finds_a_decay_inside_its_bounds_with_honest_errors(rate: float, amplitude: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 3.0, 300)
    y = amplitude * np.exp(-rate * t) + rng.normal(scale=0.01, size=t.size)
    problem = Problem(lambda x: x[0] * np.exp(-x[1] * t) - y, np.array([1.0, 1.0]), np.array([0.1, 0.1]),
                      np.array([5.0, 5.0]), np.array([1e-6, 1e-6]))
    solution = levenberg_marquardt(problem, [Group(np.array([0])), Group(np.array([1]))])
    stderr = np.sqrt(np.diag(solution.cov))
    assert abs(solution.x[0] - amplitude) < 5.0 * stderr[0]
    assert abs(solution.x[1] - rate) < 5.0 * stderr[1]


def test_a_bound_holds_even_when_the_data_want_beyond_it() -> None:
    t = np.linspace(0.0, 1.0, 50)
    problem = Problem(lambda x: x[0] * t - 3.0 * t, np.array([0.5]), np.array([0.0]), np.array([2.0]), np.array([1e-6]))
    assert levenberg_marquardt(problem, [Group(np.array([0]))]).x[0] == pytest.approx(2.0)


def test_correlation_length_is_one_for_white_noise_and_grows_with_smoothing() -> None:
    rng = np.random.default_rng(3)
    white = rng.normal(size=20000)
    assert correlation_length(white) == pytest.approx(1.0, abs=0.05)
    smooth = np.convolve(white, np.ones(10) / 10, mode="same")
    assert correlation_length(smooth) > 10.0


def _heave_signals(theta: np.ndarray, lag_s: float, seed: int) -> Signals:
    """Twelve 4 s windows of vertical commands (steps through the deadband, both ways) flown by the model."""
    rng = np.random.default_rng(seed)
    dt, per = 0.02, 200
    levels = rng.choice([-0.5, -0.2, 0.0, 0.2, 0.35, 0.5], size=(WINDOWS, 4))
    commands = np.zeros((WINDOWS * per, 4))
    commands[:, 2] = commands[:, 3] = np.repeat(levels.ravel(), per // 4)
    each = Windows(np.arange(0, WINDOWS * per, per), per)  # every window from rest at 1.5 m, as the refinement cuts them
    z = simulate_heave(theta, commands, each, np.full(WINDOWS, 1.5), np.zeros(WINDOWS), dt, lag_s, lambda w: 0.05 * w + 0.3 * w * np.abs(w)).ravel()
    z = z + rng.normal(scale=0.005, size=z.size)
    n = z.size
    rate = {"heave": np.gradient(z, dt)[:-1]}
    return Signals(dt, commands, rate, {}, {}, {}, {"heave": z}, np.ones(n, bool), np.zeros(n - 1))


WINDOWS = 12


@pytest.mark.parametrize("seed", [1])
def test_refine_heave_recovers_the_model_from_a_start_15_percent_off(seed: int) -> None:
    truth = np.array([0.45, 0.6, 0.5, 1.3, 0.08])  # buoyancy/m, thrust/m, reverse ratio, ms/mh, deadband
    lag = 0.08
    sig = _heave_signals(truth, lag, seed)
    start = AxisFit(HEAVE_NAMES, np.array([0.45 * 1.1, 0.6 * 0.85, 0.6 * 0.85 * 0.5 * 1.15, 1.3 * 0.85]), np.eye(4), 0.0, 1.0, 0)
    refit = refine_heave(sig, start, lag, 0.05, lambda w: 0.05 * w + 0.3 * w * np.abs(w))
    c = dict(zip(refit.fit.names, refit.fit.coef))
    assert c["buoyancy_per_mass"] == pytest.approx(0.45, rel=0.01)
    assert c["thrust_per_mass"] == pytest.approx(0.6, rel=0.01)
    assert c["reverse_thrust_per_mass"] / c["thrust_per_mass"] == pytest.approx(0.5, rel=0.02)
    assert c["surge_per_heave_mass"] == pytest.approx(1.3, rel=0.05)
    assert refit.deadband == pytest.approx(0.08, abs=0.005)
    stderr = np.sqrt(np.diag(refit.fit.cov))
    assert abs(c["surge_per_heave_mass"] - 1.3) < 5.0 * stderr[3]
