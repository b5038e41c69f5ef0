"""Fitting the gates' thresholds on labelled continuous clips, as the paper fits its threshold.

The paper fits its anchoring threshold on the first 60 % of each clip. Here,
from the contact clip's contact frames (positives) and the hover clip's frames
(negatives), both restricted to their first 60 %:

- ``contact_edge``: the edge sharpness (steepest depth gradient at the
  fingertip) by the same margin rule as the depth gates, its hardest press
  being the sharpest edge a press holds for ``down_frames`` consecutive frames
  (what landing and confirming a touch needs); when the rule cannot hold, the
  middle of the range of thresholds with the best per-frame balanced accuracy,
  with a warning. The clips are then replayed with it, because the anchoring
  score counts from each landing on a contact edge;
- ``contact_projected_depth`` (the projected-light gate, which a shadow must
  pass on every frame to land, like the edge) by the same margin rule, on the
  frames where the projector's share of the light was known: its scores are the
  largest projected depth of a shadow (the share of the projector's own light
  it took: a hover none, a contact 0.4-0.5), the hardest press's being the
  largest it holds for ``down_frames`` consecutive frames, the hardest hover
  never taken below 0 (:data:`HOVER_PROJECTED_BOUND`). Where the share was
  never known (no projector stream, a static back-light replayed without its
  probe) or the gate is off, it has nothing to measure: the configured value is
  kept and the fit says why (:func:`fit_projected`). It is fitted with the edge,
  from the first replay: neither score depends on any threshold;
- ``anchor_threshold`` and ``instant_depth`` by the margin rule below, the
  instant gate kept at least as high as the anchor threshold.

**The margin rule** (issue 17, point 5). A threshold fitted just above the
hardest hover of one minute of clips fires on the first hover that comes a
little closer. So each gate's threshold (the edge's too) is placed from the two hardest
cases, not from the best balanced accuracy alone:

- the hardest negative ``n``: the largest score of any hover frame (for the
  instant gate any hover frame's core depth, landed or not: a core one edge
  wobble away from landing is as close as a landed one);
- the hardest positive ``p``: the smallest, over the contact clip's presses,
  of the press's largest score (a press is detected when its score passes
  once, so that is what must clear the threshold);
- ``sigma``: the spread (standard deviation) of the hover's closest
  approaches, its frames' nonzero scores in their top ``CLOSEST_SHARE``: how
  much one close approach differs from the next, so how much closer than the
  hardest one the next may plausibly come;
- ``threshold = n + max(MARGIN_FRACTION * (p - n), MARGIN_SIGMAS * sigma)``:
  half the gap (equal margins to both sides), and never closer to the hardest
  hover than ``MARGIN_SIGMAS`` spreads.

When the rule cannot hold (``p <= n``, or ``n + MARGIN_SIGMAS * sigma >= p``:
the clips do not separate presses from hovers by that much), the threshold
falls back to the best balanced accuracy (the paper's fit) and the fit carries
a warning saying which gate and by how much; `calibrate touch` prints it and
writes it into the fragment, so the thin margin is never silent.

The remaining 40 % is left for `feelium eval` to judge the fit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from feelium.lab.touch.evaluate import balanced_accuracy_curve, fit_threshold, split_clip

MARGIN_FRACTION = 0.5  # the threshold sits this far into the gap from the hardest hover to the hardest press
MARGIN_SIGMAS = 2.0  # ... and at least this many hover spreads above the hardest hover
CLOSEST_SHARE = 0.1  # the hover spread is that of its closest approaches: this top share of its nonzero scores
# A hand above the membrane takes none of the projector's own light (feelium.touch.roomshare.projected_depth): the
# hardest hover the projected-light gate is placed from is never below this, whatever the clips' hovers showed.
HOVER_PROJECTED_BOUND = 0.0


@dataclass(frozen=True)
class ClipSeries:
    """Per-frame series of one clip, as replay produced them."""

    label: str
    t: np.ndarray
    anchor: np.ndarray
    core_depth: np.ndarray
    edge: np.ndarray
    contact: np.ndarray  # bool: labelled contact at this frame
    projected: np.ndarray | None = None  # the projected-light gate's score (NaN where the share was unknown)


@dataclass(frozen=True)
class GateFit:
    """One depth gate's threshold and the cases it was placed between."""

    threshold: float
    hardest_negative: float
    hardest_positive: float
    sigma: float
    warning: str | None  # set when the margin rule could not hold and the balanced-accuracy fit was used
    # The clips' own hardest hover when a bound stood in for it (hardest_negative is then the bound).
    observed_negative: float | None = None

    def margins(self) -> dict[str, float]:
        return {
            "hardest_negative": round(self.hardest_negative, 4),
            "hardest_positive": round(self.hardest_positive, 4),
            "negative_margin": round(self.threshold - self.hardest_negative, 4),
            "positive_margin": round(self.hardest_positive - self.threshold, 4),
        }


@dataclass(frozen=True)
class ProjectedKept:
    """The projected-light gate left at its configured value, and why (it had nothing to measure)."""

    threshold: float
    reason: str


@dataclass(frozen=True)
class Fit:
    contact_edge: float
    anchor: GateFit
    instant: GateFit
    positives: int
    negatives: int
    edge: GateFit | None = None  # how contact_edge was placed (None: given, not fitted)
    projected: GateFit | ProjectedKept | None = None  # contact_projected_depth (None: not asked for)

    @property
    def anchor_threshold(self) -> float:
        return self.anchor.threshold

    @property
    def instant_depth(self) -> float:
        return self.instant.threshold

    @property
    def warnings(self) -> list[str]:
        gates = (self.edge, self.anchor, self.instant, self._projected_fit)
        return [g.warning for g in gates if g is not None and g.warning]

    @property
    def notes(self) -> list[str]:
        """What was not fitted and why (a gate kept at its configured value)."""
        if isinstance(self.projected, ProjectedKept):
            return [f"contact_projected_depth {self.projected.threshold:g} kept as configured: {self.projected.reason}"]
        return []

    @property
    def _projected_fit(self) -> GateFit | None:
        return self.projected if isinstance(self.projected, GateFit) else None

    def values(self) -> dict[str, float]:
        """The fitted values (a gate kept at its configured value is not among them: the fragment leaves it be)."""
        values = {
            "contact_edge": round(self.contact_edge, 4),
            "anchor_threshold": round(self.anchor_threshold, 4),
            "instant_depth": round(self.instant_depth, 4),
        }
        if self._projected_fit is not None:
            values["contact_projected_depth"] = round(self._projected_fit.threshold, 4)
        return values

    def summary(self) -> list[str]:
        """One line per gate: threshold, hardest hover and press, margins (or why it was kept); then the warnings."""
        lines = []
        gates = (
            ("contact_edge", self.edge), ("contact_projected_depth", self._projected_fit),
            ("anchor_threshold", self.anchor), ("instant_depth", self.instant),
        )  # fmt: skip
        for name, gate in gates:
            if gate is None:
                continue
            m = gate.margins()
            bound = "" if gate.observed_negative is None else f", the bound; the clips' {gate.observed_negative:.4f}"
            lines.append(
                f"{name} {gate.threshold:.4f}: hardest hover {m['hardest_negative']:.4f} "
                f"(margin {m['negative_margin']:+.4f}{bound}), hardest press {m['hardest_positive']:.4f} "
                f"(margin {m['positive_margin']:+.4f}), hover spread {gate.sigma:.4f}"
            )
        return lines + self.notes + [f"warning: {w}" for w in self.warnings]

    def to_toml(self) -> str:
        lines = [
            "# Fitted by `feelium calibrate touch` on the first 60 % of the contact and hover clips",
            f"# ({self.positives} contact frames, {self.negatives} hover frames).",
            f"# Margin rule: threshold = hardest hover + max({MARGIN_FRACTION} x gap to the hardest press, "
            f"{MARGIN_SIGMAS} x hover spread).",
        ]
        lines += [f"# {line}" for line in self.summary()]
        lines.append("[touch]")
        lines += [f"{key} = {value!r}" for key, value in self.values().items()]
        return "\n".join(lines) + "\n"


def _fit_samples(clips: list[ClipSeries], series: str) -> tuple[np.ndarray, np.ndarray]:
    """(contact-frame values, hover-frame values) of one series over the first 60 % of each clip."""
    pos, neg = [], []
    for clip in clips:
        fit = split_clip(clip.t)
        values = getattr(clip, series)
        if clip.label == "contact":
            pos.append(values[fit & clip.contact])
        elif clip.label == "hover":
            neg.append(values[fit])
    if not pos or not neg:
        raise ValueError("calibration needs a labelled continuous 'contact' clip and a 'hover' clip")
    positives, negatives = np.concatenate(pos), np.concatenate(neg)
    if positives.size == 0 or negatives.size == 0:
        raise ValueError("the clips hold no contact frames or no hover frames in their first 60 %")
    return positives, negatives


def fit_centred_threshold(positives: np.ndarray, negatives: np.ndarray) -> float:
    """The middle of the widest interval of thresholds with the best balanced accuracy (equal margin both sides).

    A threshold ``th`` counts values >= th as contact. Between neighbouring
    sorted values the balanced accuracy is constant, so every threshold in
    ``(values[i - 1], values[i]]`` scores like ``values[i]``; consecutive best
    values join into one interval.
    """
    values = np.unique(np.concatenate([positives, negatives]))
    candidates = np.append(values, values[-1] + 1e-6)  # the last: above everything
    ba = balanced_accuracy_curve(positives, negatives, candidates)
    best = ba >= ba.max() - 1e-12
    widest, centre = -1.0, float(candidates[int(np.argmax(best))])
    k = 0
    while k < candidates.size:
        if not best[k]:
            k += 1
            continue
        start = k
        while k + 1 < candidates.size and best[k + 1]:
            k += 1
        low = candidates[start - 1] if start > 0 else candidates[start]
        width = candidates[k] - low
        if width > widest:
            widest, centre = width, float(0.5 * (low + candidates[k]))
        k += 1
    return centre


def fit_edge(clips: list[ClipSeries], held_frames: int = 2) -> GateFit:
    """The contact-edge threshold by the margin rule (per-frame centred balanced accuracy when it cannot hold).

    A hover lands on one frame whose edge passes, so its score is every frame's
    edge; a press becomes a touch only when its edge passes on ``held_frames``
    consecutive frames (``[touch] down_frames``), so its score is its sharpest
    edge held that long.
    """
    pos_frames, hover = _fit_samples(clips, "edge")
    held = [replace(c, edge=_held(c.edge, held_frames)) for c in clips]
    return _gate_fit("contact_edge", pos_frames, hover, _press_maxima(held, "edge"), fit_centred_threshold)


def fit_projected(clips: list[ClipSeries], configured: float, held_frames: int = 2) -> GateFit | ProjectedKept:
    """``contact_projected_depth`` by the margin rule where the projector's share was known, else kept (with why).

    Like the edge, the gate is a landing condition a shadow must pass on every
    frame: a hover's score is each frame's projected depth, a press's the
    largest it holds for ``held_frames`` consecutive frames (``down_frames``).
    The hardest hover is the clips' hardest or :data:`HOVER_PROJECTED_BOUND`,
    whichever is higher: a hover takes none of the projector's own light, so
    one that comes as close as a hover can scores about 0 (more only through
    an error of the share); a minute of hover clips far from that (seed 32's
    lit room: -0.62) would otherwise put the gate below 0, where any hover
    whose share is a little off lands. Only frames whose share was known count
    (NaN: unknown; the pipeline then lets the shadow land, so the gate was not
    in play there). When the rule cannot hold, the per-frame centred
    balanced-accuracy fit, with a warning.

    Kept at ``configured`` (:class:`ProjectedKept`) when the gate is off, or when
    the hover clip or the contact clip's presses never had the share known: a
    recording without a projector stream, or a static back-light replayed
    without its probe, shows nothing this gate decides on, and a value fitted
    from nothing would only look measured.
    """
    if configured <= 0.0:
        return ProjectedKept(configured, "the gate is off ([touch] contact_projected_depth = 0): nothing to fit")
    known = [replace(c, projected=c.projected if c.projected is not None else np.full(c.t.size, np.nan)) for c in clips]
    pos_frames, hover = (values[np.isfinite(values)] for values in _fit_samples(known, "projected"))
    unknown = (
        "the projector's share of the light was never known on the clips' shadows "
        "(no projector stream, or a static back-light replayed without the probe)"
    )
    if hover.size == 0:
        return ProjectedKept(configured, f"no hover frame in the first 60 % has a score: {unknown}")
    held = [replace(c, projected=_held(c.projected, held_frames)) for c in known]  # type: ignore[arg-type]
    presses = _press_maxima(held, "projected")
    if presses.size == 0 or pos_frames.size == 0:
        return ProjectedKept(configured, f"no press in the first 60 % held a score for {held_frames} frames: {unknown}")
    return _gate_fit(
        "contact_projected_depth", pos_frames, hover, presses, fit_centred_threshold,
        zero_unscored=False, hover_bound=HOVER_PROJECTED_BOUND,
    )  # fmt: skip


def _held(values: np.ndarray, frames: int) -> np.ndarray:
    """Per frame, the smallest of the last ``frames`` values (the value held that long up to this frame; NaN
    when any of them is)."""
    if frames <= 1 or values.size == 0:
        return values
    padded = np.concatenate([np.full(frames - 1, values[0]), values])
    return np.lib.stride_tricks.sliding_window_view(padded, frames).min(axis=1)


def _press_maxima(clips: list[ClipSeries], series: str) -> np.ndarray:
    """The largest value of ``series`` over each press (run of contact frames) of the contact clips.

    Only presses that end inside the first 60 % count (one cut by the split is
    not a shallower press, only a shorter look at one), unless none does: then
    the contact runs inside the first 60 %, cut or not. NaN frames have no
    score; a press with none is left out.
    """
    whole: list[float] = []
    cut: list[float] = []
    for clip in clips:
        if clip.label != "contact":
            continue
        fit = split_clip(clip.t)
        values = getattr(clip, series)
        whole += _largest(values, [(a, b) for a, b in _runs(clip.contact) if b < fit.size and fit[b]])
        cut += _largest(values, _runs(clip.contact & fit))
    return np.asarray(whole or cut, float)


def _largest(values: np.ndarray, runs: list[tuple[int, int]]) -> list[float]:
    """The largest finite value in each run that has one."""
    out = []
    for a, b in runs:
        scored = values[a:b][np.isfinite(values[a:b])]
        if scored.size:
            out.append(float(scored.max()))
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def hardest_cases(press_maxima: np.ndarray, hover: np.ndarray, zero_unscored: bool = True) -> tuple[float, float, float]:
    """(hardest hover n, hardest press p, hover spread sigma) as the margin rule defines them.

    ``zero_unscored``: a hover frame scoring 0 had nothing to score (no landing, no shadow) and is left out of
    the spread; off for a gate whose scores are all measured, negative ones included (the projected depth)."""
    seen = hover[hover > 0.0] if zero_unscored else hover
    closest = seen[seen >= np.quantile(seen, 1.0 - CLOSEST_SHARE)] if seen.size else seen
    return float(hover.max()), float(press_maxima.min()), float(closest.std()) if closest.size > 1 else 0.0


def margin_threshold(n: float, p: float, sigma: float) -> float | None:
    """The margin rule's threshold between hardest hover ``n`` and hardest press ``p``; None when it cannot hold."""
    margin = max(MARGIN_FRACTION * (p - n), MARGIN_SIGMAS * sigma)
    return n + margin if p > n and n + margin < p else None


def _gate_fit(
    name: str,
    pos_frames: np.ndarray,
    hover: np.ndarray,
    press_maxima: np.ndarray,
    balanced: Callable[[np.ndarray, np.ndarray], float | None] = fit_threshold,
    *,
    zero_unscored: bool = True,
    hover_bound: float | None = None,
) -> GateFit:
    """One gate by the margin rule, else by ``balanced`` accuracy with a warning naming the gate and the gap.

    ``hover_bound``: how hard a hover can be whatever the clips showed; the hardest hover is never below it."""
    n, p, sigma = hardest_cases(press_maxima, hover, zero_unscored)
    observed = None
    if hover_bound is not None and n < hover_bound:
        observed, n = n, hover_bound
    ruled = margin_threshold(n, p, sigma)
    if ruled is not None:
        return GateFit(ruled, n, p, sigma, None, observed)
    fallback = balanced(pos_frames, hover)
    assert fallback is not None
    warning = (
        f"{name}: the hardest press ({p:.4f}) is not {MARGIN_SIGMAS:g} hover spreads ({MARGIN_SIGMAS * sigma:.4f}) "
        f"above the hardest hover ({n:.4f}); fitted by balanced accuracy instead ({fallback:.4f}): "
        "a hover a little closer than these clips' may fire; record more or closer hovers, or check the setup"
    )
    return GateFit(float(fallback), n, p, sigma, warning, observed)


def fit_gates(
    clips: list[ClipSeries], contact_edge: float | GateFit, projected: GateFit | ProjectedKept | None = None
) -> Fit:
    """Fit the depth thresholds on clips replayed with ``contact_edge`` (a value, or :func:`fit_edge`'s fit) and
    the projected-light gate ``projected`` (:func:`fit_projected`'s fit, carried into the result; None: not asked).

    ValueError naming what is missing.
    """
    edge = contact_edge if isinstance(contact_edge, GateFit) else None
    edge_value = edge.threshold if edge is not None else float(contact_edge)  # type: ignore[arg-type]
    pos, neg = _fit_samples(clips, "anchor")
    pos_core, hover_core = _fit_samples(clips, "core_depth")
    anchor = _gate_fit("anchor_threshold", pos, neg, _press_maxima(clips, "anchor"))
    instant = _gate_fit("instant_depth", pos_core, hover_core, _press_maxima(clips, "core_depth"))
    if instant.threshold < anchor.threshold:  # a press deep enough for the sustained gate is never refused at once
        instant = replace(instant, threshold=anchor.threshold)
    return Fit(
        contact_edge=edge_value, anchor=anchor, instant=instant, positives=int(pos.size), negatives=int(neg.size),
        edge=edge, projected=projected,
    )  # fmt: skip
