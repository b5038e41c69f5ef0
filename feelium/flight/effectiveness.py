"""How strongly the real blimp answers a push, learned in flight: one bounded gain per axis and direction.

The controller's config describes a nominal blimp; a real one's mass, thrust
and reverse ratio may each be off by a factor of two, so the acceleration a
motor command gives may be anywhere from an eighth to four times what the
config predicts. A loop tuned for the nominal plant then overshoots on a
strong plant (the feedback's effective gain is four times too high for the
motor lag) and cannot stop a weak one. This estimator measures the ratio
*effectiveness = measured change of rate / modelled change of rate* over
short windows with real excitation, by least squares with forgetting, and
the loops divide their forces by it. It starts at the box's *upper* bound
(assume the strongest plant: low gains, never unstable) and is bounded by
the box, so a burst of bad measurements cannot make it unsafe. Pushes of
each sign are learned apart: braking uses the reverse thrust, whose ratio
is one of the unknowns.
"""

from __future__ import annotations

import math
from collections import deque


REAL_PUSH_SLACK_S = 0.05  # the loop marks a real push after the estimate's update: a cycle late, with room
ASSURED_STANDARD_ERRORS = 2.0  # with ``change_noise``: a margin counts on the learned value this many standard errors low
# With ``steady_bias``: a side's line is used once its slope's standard error (``change_noise`` over the root of its
# information) is at most this; until then the ratio through the origin, biased but steady. Unguarded, a line through
# a first hover's few windows read anything, and 88 of 1152 flights left the altitude limits (session 30).
LINE_STANDARD_ERROR = 1.0
# ...and once a line is known, the value follows its slope whenever its standard error is at most this, and holds the
# last slope it followed otherwise (its margin fading with the spread). Chosen afresh at 1.0 in every window, a long
# still hold's fading spread handed the side back to the biased ratio (a learned 1.09 read 0.25 after 30 s: the
# session-30 review, finding 1); following a line whatever its error kept one the range noise had biased high through
# a heavy weak corner's hold, 1 of 192 held-out flights 0.100 m past the ceiling (docs/flight-robustness.md, session
# 31).
LINE_LEAVING_STANDARD_ERROR = 2.0
assert LINE_LEAVING_STANDARD_ERROR >= LINE_STANDARD_ERROR, "a line left before the error that admits it would flap"
# With ``one_way``: a window teaches only if its net push is at least this share of its pushes' sum (they keep a sign).
ONE_WAY_SHARE = 0.8


def _fold(sums: list[float], decay: float, x: float, y: float) -> float:
    """Fold one window into least-squares sums ``[sum x*x, sum x*y]`` with forgetting; the ratio they give now (0 while
    no window has carried a push)."""
    sums[0] = sums[0] * decay + x * x
    sums[1] = sums[1] * decay + x * y
    return sums[1] / sums[0] if sums[0] > 0.0 else 0.0


def _fold_affine(sums: list[float], decay: float, x: float, y: float, least_spread: float) -> tuple[float | None, float]:
    """Fold one window into the sums ``[n, sum x, sum y, sum x*x, sum x*y]`` of a line ``y = slope * x + offset`` with
    forgetting; its slope now (``None`` while the pushes' spread about their mean is under ``least_spread``: their
    differences would be noise) and that spread (the slope's information)."""
    for i, term in enumerate((1.0, x, y, x * x, x * y)):
        sums[i] = sums[i] * decay + term
    n, sx, sy, sxx, sxy = sums
    spread = sxx - sx * sx / n
    if spread <= least_spread:
        return None, 0.0
    return (sxy - sx * sy / n) / spread, spread


class Effectiveness:
    """Least-squares ratio of measured to modelled rate change over ``window_s`` windows, per push direction."""

    def __init__(self, low: float, high: float, reverse_low: float | None = None, window_s: float = 0.3,
                 memory_s: float = 6.0, min_change: float = 0.0, assuring_change: float = 0.0,
                 confirming_change: float = 0.0, shown: float | None = None, reverse_shown: float | None = None,
                 mirrored: bool = False, real_pushes_assure: bool = False, real_pushes_confirm: bool = False,
                 change_noise: float = 0.0, one_way: bool = False, steady_bias: bool = False,
                 assuring_error: float = 0.0, halving_falls: bool = False) -> None:
        """``reverse_low``: a lower bound for negative pushes (the reverse ratio is unknown too);
        ``min_change``: the smallest modelled rate change over a window that counts as excitation;
        ``confirming_change``: the smallest measured rate change (the push's way) of the windows that
        alone teach what a large push counts on (:meth:`confirmed`; 0: none do);
        ``assuring_change``: the smallest *real* rate change (modelled times learned) that may teach what
        a safety margin counts on. Small
        corrections against drift are biased high (the air's drag brakes the body along with the
        push and is credited to it), so a margin waits for a real push, such as a brake;
        ``shown``: the effectiveness a calibration flight's own pushes showed (1: the fitted model's), which a
        safety margin counts on until a real push in flight teaches it (``None``: nothing shown, the box's
        lower bound); ``reverse_shown``: the same for negative pushes, when the calibration measured them apart
        (``None``: ``shown``); ``mirrored``: the axis answers both ways alike (a yaw torque is one motor forward
        and one reversed whichever way it turns), so until a real push of one sign confirms its value, a large push
        of that sign counts on what the other sign confirmed instead of the box's upper bound (:meth:`confirmed`);
        ``real_pushes_assure``: only a window that overlaps a real push of its own sign (the loop out of hover: a
        command or a brake, :meth:`mark_real_push`) may teach the margin. Hover corrections taught corner-MtdL a
        reverse surge effectiveness twice what its brakes showed, and a speed cap that did not stop in time (flight
        seed 6: 1.50 s; docs/flight-robustness.md, session 21). A window of reverse hover corrections that merely
        overlapped a forward command's first cycles assured the reverse side at the box's strongest (corner-Mtdl,
        flight seed 4: the forward stop 1.62 s; session 24);
        ``real_pushes_confirm``: the same for what a large push counts on (:meth:`confirmed`). A hover correction
        that met a draft turning the body its way confirmed corner-MtDL's yaw at five times its answer, and both its
        turns, counting on that, reached 0.18-0.22 of the command (flight seed 5; session 24);
        ``change_noise``: the standard deviation of one window's measured rate change (the sensor's noise and the
        air's): a margin then counts on the learned value ``ASSURED_STANDARD_ERRORS`` standard errors low, so a few
        windows barely above the noise teach it nothing and many large ones teach it nearly the least squares (0:
        the least squares as it is). Three windows of a climb's onset, each changing the modelled rate by 0.03 m/s
        against 0.07 m/s of noise, taught the heave's down side 2.54 (true about 1), and a calibrated heavy corner
        climbed into the ceiling (docs/calibrate-flight.md, session 22);
        ``one_way``: a window whose pushes change sign teaches nothing (``ONE_WAY_SHARE``). Its net push is the
        difference of two, so the same rate change divided by it reads too strong: a brake's first windows, mixed with
        the command's last forward pushes, and the hover's windows mixing that brake with forward corrections taught
        corner-MtDl's reverse surge 0.33 where its brake showed 0.13-0.15; the speed cap counting on it took the
        forward lapse to 1.54 s (flight seed 19; docs/flight-robustness.md, session 28);
        ``steady_bias``: the pushes carry an estimate that moves no rate (the learned disturbance, the part
        :meth:`update` is told is ``learned``), off while it learns: each direction fits a line through the commanded
        share of its pushes with an offset (the force the model misses), not a ratio of the whole push through the
        origin. Through the origin, a hold whose disturbance was 0.2-0.7 m/s^2 off taught corner-MTdl's heave 0.25 down
        and 3.1 up where both were about 1.0; its down pushes were four times too strong and the hold under the ceiling
        swung 10.7 cm past it (flight seed 70; docs/flight-robustness.md, session 30). A line needs pushes that differ:
        until its slope is known to ``LINE_STANDARD_ERROR`` (so ``change_noise`` is required), the side keeps the ratio
        through the origin; once known, the side never returns to the ratio (see ``LINE_LEAVING_STANDARD_ERROR``);
        ``assuring_error``: what the flight teaches the margin counts only once the windows that may teach it pin the
        value to this standard error, each weighted by the noise :meth:`update` is told its measured change has (0: from
        the first such window). A window whose push was barely over ``min_change`` read the flow's noise as a change
        five times the push's, on a side still at the box's strongest: it assured the shipped config's reverse surge at
        4.0 (from the box's 0.125) and the speed cap doubled, after a board stall had left the body under the ceiling
        where the flow is noisiest (docs/flight-robustness.md, session 33);
        ``halving_falls``: once a side has a learned value (its own, or on a mirrored axis the other side's that it
        took), a window lowers it, and what it confirmed, by at most half per ``window_s`` since the side was last set
        (:meth:`_fall_limited`: a side unused for a while may halve on its first window, then at that pace); a safety
        margin (:meth:`assured`) follows the windows unlimited (``windows_taught``), a lower value being the safe side
        there. A lower value makes every push it normalises stronger, and one misread window taught a light strong
        blimp's yaw 0.19 where it held 1.52 (a hover, replies 10 ms late): the next push, divided by that, turned the
        body to 4.1 deg/s, a stop of 1.80 s (corner-mTdl; docs/flight-robustness.md, session 37; a heavy corner's
        forward surge fell alike from 1.67 to 0.30 after a reconnection in session 36, but the surge does not take
        this: tried, its heavy corners' brakes, which need the reverse value to fall within the stop, took up to 1.52
        s). Halving per window is the pace at which an untaught push escalates (``loops.ESCALATE_S``, also 0.3 s): a
        value taught weak by many windows gets there as fast as a push that had to find it. A side's first own value
        (from the box's strongest) is not limited: that is a weak blimp's brake learning its reverse side."""
        reverse_low = low if reverse_low is None else reverse_low
        if not (0.0 < low <= high and 0.0 < reverse_low <= high):
            raise ValueError(f"effectiveness bounds must satisfy 0 < low <= high, got {reverse_low}, {low}, {high}")
        if steady_bias and change_noise <= 0.0:
            # its guard is the slope's standard error: without a noise, a first hover's few windows would fit any line
            raise ValueError("steady_bias needs change_noise > 0: a line is used only once its slope is known")
        self.lows = [reverse_low, low]
        self.high = high
        self.window_s, self.memory_s, self.min_change = window_s, memory_s, min_change
        self.assuring_change = assuring_change
        self.assuring_samples = [0, 0]
        self.real_push_t: list[float | None] = [None, None]  # per sign, the loop's last cycle out of hover pushing so
        self.real_pushes_assure = real_pushes_assure
        self.real_pushes_confirm = real_pushes_confirm
        self.confirming_change = confirming_change
        self.shown_by_side = [shown if reverse_shown is None else reverse_shown, shown]
        self.confirming_samples = [0, 0]
        self.values = [high, high]  # [push < 0, push > 0]
        self.halving_falls = halving_falls
        self.windows_taught = [high, high]  # ``values`` before ``halving_falls`` limits their fall
        self._sums = [[0.0, 0.0], [0.0, 0.0]]  # per direction: sum x*x, sum x*y
        self.steady_bias = steady_bias
        self._affine_sums = [[0.0] * 5, [0.0] * 5]  # with ``steady_bias``, per direction: see :func:`_fold_affine`
        # with ``steady_bias``, per direction: the last slope the value followed, held while the line's spread no
        # longer supports it (``None``: no line known yet, the side on the ratio; once known, never the ratio again)
        self._line_slopes: list[float | None] = [None, None]
        self._strong_sums = [[0.0, 0.0], [0.0, 0.0]]  # the same over real pushes only
        self._assuring_sums = [[0.0, 0.0], [0.0, 0.0]]  # the same over the windows that may teach a margin
        self.change_noise = change_noise
        self.assuring_error = assuring_error
        self._assuring_precision = [0.0, 0.0]  # per direction: sum of (x / noise)^2 over the windows that may assure
        # per direction: sum x*x over independent windows (they overlap); with ``steady_bias`` once a line is used, the
        # spread of its commanded pushes instead
        self._information = [0.0, 0.0]
        self.strong_values = [high, high]
        # (t, modelled push integral, its magnitude's integral, the integral of its commanded share, measured rate)
        self._history: deque[tuple[float, float, float, float, float]] = deque()
        self._push_integral = 0.0
        self._gross_integral = 0.0
        self._commanded_integral = 0.0
        self.one_way = one_way
        self.mixed_windows = 0  # with ``one_way``: windows over ``min_change`` not taught from, changing sign
        self.samples = [0, 0]
        self.mirrored = mirrored
        self._set_t: list[list[float | None]] = [[None, None], [None, None]]  # per [values, strong_values], side: when set

    def value(self, push: float) -> float:
        """The effectiveness for a push of this sign (the larger one for no push: the safe side).

        On a mirrored axis a sign no window has taught yet takes what the other sign learned, as :meth:`confirmed`
        does: a heavy weak blimp drifting one way all through its hover learned only that side, and the push braking
        the drift back was normalised by the box's strongest, a sixteenth of what it needed (corner-Mtdl, flight
        seed 25: a stop that never completed; docs/flight-robustness.md, session 24)."""
        if not push:
            return max(self.values)
        side = self._taught_side(push)
        return self.values[1 if push > 0.0 else 0] if side is None else self.values[side]

    def is_taught(self, push: float) -> bool:
        """Whether :meth:`value` for a push of this sign is learned (not the box's strongest it starts from)."""
        return self._taught_side(push) is not None

    def _taught_side(self, push: float) -> int | None:
        """The side whose learned value a push of this sign takes: its own once a window taught it, else on a
        mirrored axis the other's, else ``None``."""
        return self._side_counted(self.samples, push)

    def confirmed(self, push: float) -> float:
        """The effectiveness for a large push: learned from real pushes only once one taught it, else the
        box's upper bound. Small corrections against a steady draft teach a value far too low (a steady force
        that changes no rate looks ineffective), and a turn normalised by it would push several times
        too hard; hover corrections may use :meth:`value`, a large push waits for a real one.

        On a mirrored axis a sign nothing has confirmed takes the other sign's confirmed value. On a heavy, weak
        blimp the box's upper bound is 20 times its answer: a turn normalised by it reached 1.5 of the commanded
        20 deg/s, too little ever to confirm, and a turn the other way was braked at +-0.35 of the motors through
        its brake and settling, where the hover after it pushed +-0.68 (corner-MtDL, flight seed 2: that turn's
        lapse 1.76 s, now 0.96 s; docs/flight-robustness.md, session 20).
        """
        side = self._confirmed_side(push)
        return self.high if side is None else self.strong_values[side]

    def is_confirmed(self, push: float) -> bool:
        """Whether :meth:`confirmed` is a learned value for a push of this sign (not the box's upper bound)."""
        return self._confirmed_side(push) is not None

    def _confirmed_side(self, push: float) -> int | None:
        """The side whose confirmed value a push of this sign takes: its own, else on a mirrored axis the other's,
        else ``None`` (nothing confirmed: the box's upper bound)."""
        return self._side_counted(self.confirming_samples, push)

    def _side_counted(self, counts: list[int], push: float) -> int | None:
        """A push's own side if ``counts`` has windows on it, else on a mirrored axis the other side if it has."""
        side = 1 if push > 0.0 else 0
        if counts[side]:
            return side
        if self.mirrored and counts[1 - side]:
            return 1 - side
        return None

    def assured(self, push: float) -> float:
        """The effectiveness a safety margin may count on: the learned one once a real push taught it, else
        the one a calibration showed (within the box), else the box's lower bound. A calibration's brakes
        taught a point estimate as an in-flight brake does, from more and longer steps."""
        side = 1 if push > 0.0 else 0
        shown = self.shown_by_side[side]
        if self.assuring_samples[side]:
            return self._low_end(side)
        return self.lows[side] if shown is None else min(max(shown, self.lows[side]), self.high)

    def _low_end(self, side: int) -> float:
        """The learned value ``ASSURED_STANDARD_ERRORS`` standard errors low (its least squares' error: the window's
        noise over the root of the information), within the box. Without ``change_noise``: the least squares over the
        assuring windows alone, never above the learned value. Hover corrections after a brake kept teaching the value
        a cap counted on, and a force the model misses (a draft, the drag it underrates) makes them read strong
        (the session-28 review, finding 5; docs/flight-robustness.md)."""
        if not self.change_noise:
            assuring = self._assuring_sums[side]
            if assuring[0] <= 0.0:  # no assuring window carried a push
                return self._margin_value(side)
            return min(self._margin_value(side), max(assuring[1] / assuring[0], self.lows[side]))
        information = self._information[side]
        if information <= 0.0:
            return self.lows[side]
        low_end = self._margin_value(side) - ASSURED_STANDARD_ERRORS * self.change_noise / math.sqrt(information)
        return max(low_end, self.lows[side])

    def counts_on_shown(self, push: float) -> bool:
        """Whether :meth:`assured` is the calibration's value: nothing in flight has taught it yet, or not yet to
        ``assuring_error`` (``assuring_samples`` counts only the windows since the gate opened)."""
        side = 1 if push > 0.0 else 0
        return self.shown_by_side[side] is not None and not self.assuring_samples[side]

    def lowest(self, push: float) -> float:
        """The box's lower bound for a push of this sign: what a push must be scaled by to act on every plant."""
        return self.lows[1 if push > 0.0 else 0]

    def update(self, t: float, dt: float, push: float, measured_rate: float | None, learned: float = 0.0,
               noise: float = 0.0) -> None:
        """Fold in one cycle: the modelled acceleration ``push`` held over ``dt`` and the measured rate at ``t``;
        ``learned``: the share of ``push`` that is an estimate, not a command (the disturbance: see ``steady_bias``);
        ``noise``: the standard deviation of a window's measured change now (see ``assuring_error``)."""
        self._push_integral += push * dt
        self._gross_integral += abs(push) * dt
        self._commanded_integral += (push - learned) * dt
        if measured_rate is None or not math.isfinite(measured_rate):
            self._history.clear()  # a gap breaks the windows
            return
        self._history.append((t, self._push_integral, self._gross_integral, self._commanded_integral, measured_rate))
        while len(self._history) >= 2 and self._history[1][0] <= t - self.window_s + 1e-9:
            self._history.popleft()  # keep the newest sample at or before the window's start
        t0, integral0, gross0, commanded0, rate0 = self._history[0]
        if t - t0 < self.window_s - 1e-6:
            return
        x = self._push_integral - integral0
        if abs(x) < self.min_change:
            return
        if self.one_way and abs(x) < ONE_WAY_SHARE * (self._gross_integral - gross0):
            self.mixed_windows += 1
            return
        y = measured_rate - rate0
        side = 1 if x > 0 else 0
        decay = math.exp(-dt / self.memory_s)
        # A window shares all but ``dt`` of its span with the one before: window_s / dt of them are one measurement.
        overlap = min(1.0, dt / self.window_s)
        ratio = _fold(self._sums[side], decay, x, y)
        self._information[side] = self._information[side] * decay + x * x * overlap
        if self.steady_bias:
            commanded = self._commanded_integral - commanded0
            slope, spread = _fold_affine(self._affine_sums[side], decay, commanded, y, max(self.min_change ** 2, 1e-12))
            known = self._line_slopes[side] is not None
            bound = LINE_LEAVING_STANDARD_ERROR if known else LINE_STANDARD_ERROR
            if slope is not None and self.change_noise <= bound * math.sqrt(spread * overlap):
                self._line_slopes[side] = slope
            held = self._line_slopes[side]
            if held is not None:
                self._information[side] = spread * overlap
                ratio = held
        learned = min(max(ratio, self.lows[side]), self.high)
        self.windows_taught[side] = learned
        self.values[side] = self._fall_limited(0, self.values, self.samples, side, t, learned)
        self.samples[side] += 1
        real = self._overlaps_real_push(t, side)
        # the change it made (modelled times learned), not the modelled
        if (real or not self.real_pushes_assure) and abs(x) * self._margin_value(side) >= self.assuring_change:
            _fold(self._assuring_sums[side], decay, x, y)
            if noise > 0.0:
                self._assuring_precision[side] = self._assuring_precision[side] * decay + (x / noise) ** 2 * overlap
            if not self.assuring_error or self.assuring_samples[side] or self._assuring_precision[side] * self.assuring_error ** 2 >= 1.0:
                self.assuring_samples[side] += 1
        if self.confirming_change and abs(y) >= self.confirming_change and x * y > 0.0 and (real or not self.real_pushes_confirm):
            confirmed = min(max(_fold(self._strong_sums[side], decay, x, y), self.lows[side]), self.high)
            self.strong_values[side] = self._fall_limited(1, self.strong_values, self.confirming_samples, side, t, confirmed)
            self.confirming_samples[side] += 1

    def _fall_limited(self, kind: int, values: list[float], counts: list[int], side: int, t: float, new: float) -> float:
        """``new`` for ``values[side]`` (``kind`` 0: the learned values, 1: the confirmed), with ``halving_falls`` no
        lower than half of what a push of that side counted on per ``window_s`` since it was last set (at most one
        halving at a time: a side unused for a while still moves by half per window of fresh evidence)."""
        before = self._side_counted(counts, 1.0 if side else -1.0)
        last = self._set_t[kind][side]
        self._set_t[kind][side] = t
        if not self.halving_falls or before is None:
            return new
        elapsed = self.window_s if last is None else min(max(t - last, 0.0), self.window_s)
        return max(new, values[before] * 0.5 ** (elapsed / self.window_s))

    def _margin_value(self, side: int) -> float:
        """What a safety margin starts from: the windows' own value, unlimited (a lower value is the safe side there),
        or the value pushes count on if that is lower (never more than what a push is normalised by)."""
        return min(self.windows_taught[side], self.values[side])

    def mark_real_push(self, t: float, push: float) -> None:
        """The loop pushes out of hover at ``t`` (a command or a brake) with this sign (see ``real_pushes_assure``)."""
        if push:
            self.real_push_t[1 if push > 0.0 else 0] = t

    def _overlaps_real_push(self, t: float, side: int) -> bool:
        """Whether the window ending at ``t`` overlaps a real push of side ``side``'s sign (a command or a brake: the
        loop out of hover in the window; see ``real_pushes_assure``)."""
        pushed = self.real_push_t[side]
        return pushed is not None and t - pushed <= self.window_s + REAL_PUSH_SLACK_S

    def as_dict(self) -> dict[str, float | int | None]:
        """For health, per direction: the learned value pushes are normalised by and how many windows taught it (with
        ``halving_falls``, ``*_windows``: what the windows read before the limit on a fall); what a large push counts on
        (``confirmed``: ``None`` while nothing confirmed it, so such a push escalates from the box's strongest) and
        how many windows confirmed it; what a safety margin counts on (``assured``); with ``one_way``, how many windows
        taught nothing, their pushes changing sign; with ``steady_bias``, the line each side follows or holds, as the
        value it gives within the box (``*_line``: ``None`` while the side is on the ratio through the origin)."""
        health: dict[str, float | int | None] = {
            "reverse": round(self.values[0], 3), "forward": round(self.values[1], 3),
            "reverse_samples": self.samples[0], "forward_samples": self.samples[1]}
        if self.halving_falls:  # what the windows read, before the limit on a fall (the margins count on it)
            health["reverse_windows"], health["forward_windows"] = (round(v, 3) for v in self.windows_taught)
        if self.one_way:
            health["mixed_windows"] = self.mixed_windows
        if self.steady_bias:
            for side, name in enumerate(("reverse", "forward")):
                slope = self._line_slopes[side]
                health[f"{name}_line"] = None if slope is None else round(min(max(slope, self.lows[side]), self.high), 3)
        for side, name in enumerate(("reverse", "forward")):
            push = 1.0 if side else -1.0
            health[f"{name}_confirmed"] = round(self.confirmed(push), 3) if self.is_confirmed(push) else None
            health[f"{name}_confirming_samples"] = self.confirming_samples[side]
            health[f"{name}_assured"] = round(self.assured(push), 3)
        return health
