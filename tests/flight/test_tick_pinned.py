"""The control tick's outputs, pinned bit for bit on seeded flights.

Speed-ups of the tick (the MSP framing, the controller's arithmetic) must not change what it
commands. These digests were computed with the code before any of them (commit 5ff8adb; the two flights
that hover in drafts re-pinned on 1550168, whose controller holds a reversing motor's partner and smooths the
hover heading (issue 13), before the speed-ups were merged onto it, and equal after; all three re-pinned in session 15 when the
simulated board began counting its physics steps instead of accumulating them: its sensor samples now fall on
an exact 20 ms grid, not one float drift nudged by a step now and then, so every flight sees other noise; the
controller's session 15 change leaves all three unchanged, computed with and without it; ``fitted_still_air``
re-pinned in session 17: its trusted model's held `up` and `down` follow the rangefinder at half the altitude
observer's bandwidth (``HELD_CLIMB_OBSERVER_SHARE``; with the share set to 1 the old digest comes back, and the
other two flights, on a doubted model, are unchanged); the two doubted-model flights re-pinned in session 20 (branch
i13seed2): the yaw's confirmed effectiveness is mirrored, and the right turn's brake (a negative push, none confirmed
yet) counts on the positive sign's confirmed 0.91 instead of the box's 4.0 for the 0.12 s it lasts: the yaw rate is
under 3 deg/s 0.28 / 0.22 s after the release instead of 0.54 / 0.48 s, never below 0 (``fitted_still_air``, whose
box is 1, unchanged); the same two re-pinned in session 21 (branch i13seeds3) for the hover heading return limit
(``HeadingLoop._limit_return``) alone, computed with each of that session's three changes switched off in turn (the
speed cap taught by real pushes only and the turn escalation leave all three digests as they were; with the limit
off the old digests come back): from t = 2.8 s, in the scripted forward, the hover correction of the heading is
braked sooner, the yaw rate 1.0-1.2 deg/s where it was 1.5 (2.9-4.0 s); all three re-pinned in session 22 (branch
i13turn): a turn's brake follows a reference that lands on zero through the box's longest motor lag (``HeadingLoop.brake``)
instead of a linear ramp, and the rate in it is predicted over that lag; every cycle's commands are as before up to
the right turn's release at 5.2 s and first differ in the brake's first cycles (5.22-5.24 s; in ``fitted_still_air``,
whose box is 1, only the reference's shape changed; the same branch's lag-delayed windows were reverted before the
merge, and ``stall_and_lag`` is this digest). ``drafts_dropouts`` and ``fitted_still_air`` were also
re-pinned in session 22 (branch i13heave, on the code before i13turn) for one of its three changes alone, the altitude disturbance learning
nothing, in a held climb or descent, for the box's longest motor lag after a cycle at a motor limit
(``AltitudeLoop``'s ``settling``; with it off the old digests come back, and the heave margin's standard errors and
the reference's braking floor leave all three as they were): their vertical force meets a motor limit in the
scripted `up` (6.0-7.6 s), the disturbance then waits 0.16 / 0.08 s before it learns, and differs by at most 0.061 /
0.009 m/s^2 afterwards, the altitude estimate by 4.7 / 0.6 cm (``stall_and_lag`` unchanged). All three re-pinned in
session 23 for the altitude hold's end of a stop (``AltitudeLoop``): a settling stop holds the altitude's recent mean
(``REST_MEAN_TAU_S``) instead of its last estimate, and outside the limits the push back inside counts on the assured
effectiveness (``_effectiveness``) and a settling stop does not wait there; the body's simulation lost its scalar
``np.clip`` calls in the same change and left the three digests as they were. ``drafts_dropouts`` and ``stall_and_lag``
re-pinned again in session 23 for a held command's speed predicted over the box's longest lag (``SurgeLoop``) and the
hover heading loop taking over at 1.5 deg/s (``HOVER_ENGAGE_YAW_DPS``; 2 before); ``fitted_still_air``, whose box is 1
(the longest lag is the config's) and whose still air never turns the body that fast, is as it was. The same two
re-pinned a third time in session 23 for the hover's damping at full gain above 2 deg/s (``HOVER_FIRM_YAW_DPS``;
``fitted_still_air`` unchanged). ``drafts_dropouts`` and ``stall_and_lag`` re-pinned in session 24 for four of
its changes (each step computed on its own branch commit): a held turn's rate predicted over the box's longest lag,
a mirrored axis' untaught sign taking the other's learned value and a window assuring only the sign of the real push
it overlaps (together: 4eb9f070 / bab64245), a held command's surge push escalating from the box's strongest until a
window confirms its sign (521f5ae8 / 14673487), a hover heading correction of an untaught sign escalating alike
(3ee77e36 / 8708d9d9), and only a window over a real push confirming the yaw (the digests below); the push back
inside the altitude limits in a held climb left both as they were, and ``fitted_still_air`` (box 1: nothing to
escalate, the longest lag the config's) is unchanged by all of them. All three re-pinned in session 25 for health
alone: the estimates gained each loop's ``*_escalating`` and each effectiveness side's ``*_confirmed``,
``*_confirming_samples`` and ``*_assured``; hashed with those keys left out the three digests are as they were
(f3b6603c / 6efe3247 / f62fdd29), and the one-line reset of the hover escalation after a turn changed none of them.
``drafts_dropouts`` and ``stall_and_lag`` re-pinned in session 27 for a hover heading correction braking a rate over 2
deg/s mixed past the box's widest deadband (``HeadingLoop.firm_against_rate``): their commands first differ at 2.02 /
1.97 s, the first of 13 / 11 such cycles; the same session's brake escalating when nothing confirmed its sign leaves
all three as they were (computed with each change switched off in turn), and ``fitted_still_air`` (box 1: the
widest deadband is the config's) is unchanged. All three re-pinned again in session 27 for the altitude observer
taking the range slope as its climb rate, not brought forward by the model's acceleration, while the disturbance
is frozen by a partner's hand or by being far below the target (``AltitudeObserver._correct_climb_rate``): their
commands first differ at 8.42 / 8.44 s, in the scripted softening (30 such cycles), and in ``stall_and_lag`` at
6.80 s, below the target after the stall (39). All three re-pinned in session 28: the surge's effectiveness reports
``mixed_windows`` in health (``fitted_still_air``'s commands are unchanged: with that key left out its digest is as
it was), and in the two doubted-model flights surge windows whose pushes change sign teach nothing (their commands
first differ at 1.74 / 1.75 s) and a held command counts on the confirmed surge value (alone: 10.24 / 2.39 s); with
both switched off and the key left out all three digests are as they were. ``stall_and_lag`` re-pinned again in
session 28 for the surge margin's own least squares over its assuring windows (``Effectiveness._low_end``): every
cycle's commands are as before; at the end health's surge ``forward_assured`` and ``reverse_assured`` read 0.782 / 0.934
(0.814 / 0.961 before). ``drafts_dropouts`` re-pinned in session 29 for the settle after a turn's brake mixing its
push past the box's widest deadband while the rate is over 2 deg/s (``HeadingLoop.firm_against_rate`` while
settling): its commands first differ at 5.70 s, the first of 3 such cycles after the right turn's brake; the other
two flights never settle that fast and are as they were. ``drafts_dropouts`` re-pinned in session 30 for the heave's
line through the commanded pushes (``Effectiveness(steady_bias=True)``), ``stall_and_lag`` for that line and the
disturbance's slew from the climb rate (``DISTURBANCE_SLEW_M_S3``), each switched off in turn; ``fitted_still_air``,
whose box is 1, is as it was. ``drafts_dropouts`` and ``stall_and_lag`` re-pinned in session 31 for a hover surge
correction counting on no less than the other side's learned value over ``HOVER_SIDES_APART``: their commands first
differ at 3.22 / 3.23 s, after the `forward`'s brake; session 31's heave line kept once known changed no digest. All three re-pinned in session 32 for health alone: the heave
effectiveness shows each side's line (``reverse_line``, ``forward_line``, within the box: ``fitted_still_air``'s box is
1, so its lines read 1.0 where their slopes are 1.06 / 1.09); hashed with those keys left out the three digests are as
they were (ea6a57ae / 977c9bcd / 8119db57). ``drafts_dropouts`` and ``stall_and_lag`` re-pinned in session 33 for the
surge margin waiting until its windows pin the value (``Effectiveness(assuring_error=...)``): their commands first
differ at 9.10 / 9.00 s, in the soften before the ``backward`` (at the end, the surge's ``forward_assured`` reads
0.988 -> 1.149 and 0.722 -> 0.713); ``fitted_still_air`` is as it was. All three re-pinned later in session 33 for
health alone: the flow noise measured in flight (``flow_noise_rad_s``); every cycle's commands are as before.
All three re-pinned in session 36 for health alone: the altitude's recovery after an outage (``altitude_recovering``,
``False`` at the end of each: the stall's recovery ends at the scripted ``up``); hashed with that key left out the three digests are as they were (859eb7a1 / d8a16e35 /
37a16537): the recovery's margin and the ceiling rule act only back from an outage past a limit, which none of these
flights has (the stall's body stays inside them). All three re-pinned in session 37 for the yaw's learning: a learned
value falls by at most half per window (``Effectiveness(halving_falls=True)``), a window whose pushes change sign
teaches it nothing (``one_way``), and the least drag the box allows is added back to the gyro's rate
(``YawEstimate``); ``drafts_dropouts`` and ``stall_and_lag`` first differ at 2.32 / 2.33 s, in the hover before the
`forward` (413 / 392 of their 600 / 598 cycles), and ``fitted_still_air``'s commands are all as they were (its
health's yaw values are not: the drag added back). With the three changes off the old digests come back (checked on
the code before them). Then all three for health alone: the yaw shows what its windows read before the limit on a
fall (``reverse_windows``, ``forward_windows``); hashed with those keys left out the digests are as they were
(5b813f42 / 2477ca0e / 6155c056). The digests below are all of it: every
cycle's four commands, microseconds, mode and estimates, as ``repr`` of the floats, over flights
that visit hold, each motion command, release, softening, a climb to the ceiling, rangefinder
dropouts, drafts, a stalled link with its flood of replies and a lagging one. A change in the last
bit of any float changes the digest.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace

import pytest

from feelium.daemon.config import Config
from feelium.flight.blimp_model import DraftParams
from feelium.flight.faulty_link import LinkFaults, Window
from feelium.flight.setpoint import HOLD, Setpoint, setpoint_for_motion
from feelium.flight.sim_board import BoardParams, SensorParams, board_with
from feelium.lab.flight.simulation import SimFlight

CONFIG = Config().flight
SCRIPT = (  # (until s, motion command or setpoint)
    (1.5, None), (3.0, "forward"), (4.0, None), (5.2, "turn_right"), (6.0, None), (7.0, "up"),
    (7.6, None), (8.4, "down"), (9.0, "soften"), (10.0, "backward"), (10.8, "turn_left"),
    (11.5, Setpoint(altitude_m=1.2, heading_deg=30.0)), (12.0, None),
)


def _setpoint(t: float) -> Setpoint:
    for until, what in SCRIPT:
        if t < until:
            if isinstance(what, Setpoint):
                return what
            if what == "soften":
                return setpoint_for_motion(None, CONFIG, soften=True)
            return setpoint_for_motion(what, CONFIG)
    return HOLD


def _digest(flight: SimFlight, seconds: float) -> str:
    h = hashlib.sha256()
    end = flight.t + seconds - 1e-9
    while flight.t < end:
        out = flight.step(_setpoint(flight.t + flight.period))
        h.update(repr((out.commands, out.motors_us, out.mode, out.altitude_m, out.altitude_target_m, out.climb_m_s,
                       out.heading_deg, out.heading_target_deg, out.speed_m_s, out.battery, out.speed_measured)).encode())
    estimates = flight.controller.estimates(flight.t)  # type: ignore[attr-defined]
    h.update(repr(sorted(estimates.items())).encode())
    h.update(repr(sorted(flight.client.health().items())).encode())
    return h.hexdigest()[:24]


FLIGHTS = {
    "drafts_dropouts": (
        CONFIG,
        board_with(BoardParams(drafts=DraftParams(), sensors=SensorParams(range_dropout_probability=0.1)), z=1.5),
        None,
        "82c7d15e8cdfb0e69c596a33",
    ),
    "fitted_still_air": (
        replace(CONFIG, plant_uncertainty=1.0),
        board_with(BoardParams(drafts=None), z=2.2),
        None,
        "6287e6296c8c8a317d3ea4a4",
    ),
    "stall_and_lag": (
        CONFIG,
        board_with(BoardParams(drafts=DraftParams()), z=1.5),
        LinkFaults(stalls=(Window(3.5, 4.1),), lag_s=0.012),
        "4eaa3c0d0fe975a021008ecf",
    ),
}


@pytest.mark.parametrize("name", sorted(FLIGHTS))
def test_the_ticks_commands_are_those_pinned(name: str) -> None:
    config, board, faults, expected = FLIGHTS[name]
    flight = SimFlight(config, board, seed=7, faults=faults)
    assert _digest(flight, 12.0) == expected
