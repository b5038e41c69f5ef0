"""The fastest speed a plant can stop from in time: what issue 13's cruise goal is judged against.

A heavy blimp with weak reverse thrust cannot stop the commanded cruise within the stop goal's 1.0 s, whatever
the controller does (docs/calibrate-flight.md, session 17, second section); the project's decision (the section
"Decision: how the cruise goal is judged ...") is that safety wins and the cruise is judged against
``min(commanded, v_stop)``. ``v_stop`` comes from the plant's *true* physics, not from any fit: the simulator's
own model (``blimp_model.step`` at the simulator's physics step) cruises steadily at a speed in still air (the
motors' lagged thrust holding the drag), then both horizontal motors go to full reverse at the controller's
output limit at t = 0 and stay there; the stop time is the first time the forward speed is under the stop
goal's 5 cm/s. That is the best any controller with that output limit could do: it includes the motor lag
unwinding the cruise thrust, the reverse thrust through the deadband, the added mass and the drag, and leaves
out what a controller adds (the command slew, about 70 ms at the shipped 25 /s; sensing; margins). ``v_stop``
is the largest cruise whose stop time is within the limit, found by bisection (the stop time grows with the
speed).
"""

from __future__ import annotations

from dataclasses import replace

from feelium.flight.blimp_model import BlimpParams, BlimpState, step
from feelium.flight.sim_board import PHYSICS_DT
from feelium.lab.flight.safety import GOALS

STOPPED_M_S = 0.05  # the stop goal's threshold (docs/flight-robustness.md)
HORIZON_S = 10.0  # a stop that takes longer is reported as this


def stop_time(blimp: BlimpParams, speed: float, command: float, dt: float = PHYSICS_DT) -> float:
    """Seconds from a steady cruise at ``speed`` to under ``STOPPED_M_S`` with both horizontal motors at ``command``.

    The body is held at its altitude (no heave, no yaw: the two motors act alike), in still air."""
    drag = blimp.linear_drag_n_per_m_s * speed + blimp.quadratic_drag * speed * speed
    hover = blimp.net_buoyancy_n / 2.0
    state, t = BlimpState(z=1.5, u=speed, thrust_n=(drag / 2.0, drag / 2.0, hover, hover)), 0.0
    while state.u >= STOPPED_M_S and t < HORIZON_S:
        state = replace(step(blimp, state, (command, command, 0.0, 0.0), dt), z=1.5, w=0.0)
        t += dt
    return t


def fastest_stoppable(blimp: BlimpParams, command: float, within_s: float = 1.0, dt: float = PHYSICS_DT,
                      high_m_s: float = 2.0, iterations: int = 24) -> float:
    """The largest cruise speed (m/s) that ``command`` on both horizontal motors stops within ``within_s``
    (to ``high_m_s / 2^iterations``; ``high_m_s`` if even that stops in time)."""
    if stop_time(blimp, high_m_s, command, dt) <= within_s:
        return high_m_s
    lo, hi = STOPPED_M_S, high_m_s
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stop_time(blimp, mid, command, dt) <= within_s else (lo, mid)
    return lo


def cruise_target(commanded_m_s: float, blimp: BlimpParams, max_output: float, within_s: float = GOALS["stop_s"]) -> dict[str, float]:
    """What a held ``forward`` on ``blimp`` is judged against: the commanded speed, or the fastest the plant can
    stop from within ``within_s`` at the controller's output limit ``max_output`` if that is lower."""
    v_stop = fastest_stoppable(blimp, -max_output, within_s)
    return {"commanded_m_s": commanded_m_s, "v_stop_m_s": v_stop, "cruise_target_m_s": min(commanded_m_s, v_stop)}
