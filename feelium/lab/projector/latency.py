"""The projector-to-camera latency measured from a calibration recording.

The touch path mixes the projector frames lit during each camera exposure, ``[touch] projector_latency_s``
after the daemon handed them to the display (:func:`feelium.touch.settle.exposure_shares`). That latency was a
setting, never measured; a projector slower than assumed by 50-100 ms mixes the wrong frames at every scene
cut (docs/touch.md, the hostile review of issue 17). A calibration recording has the data: the projector
stream says when each pattern went up, the camera's frames what the membrane showed, and a camera frame whose
exposure integrates a switch from pattern ``a`` to ``b`` is ``(1 - f) a + f b``, ``f`` its overlap with ``b``'s
light. So:

1. the latency is first found on a grid as the one whose exposure weights best explain every camera frame as a
   mix of per-pattern images (least squares over the images, the residual compared across latencies; frames
   reduced to a coarse grid over the sensitive patch, which loses nothing of a pattern's mean light mix),
   over the setting's whole range; a best that does not clearly beat every latency more than an exposure away
   (free images let a latency a few patterns off fit too, only worse) is a refusal;
2. at that latency, each camera frame whose exposure straddles exactly one switch gives its own estimate:
   its observed share ``f`` of the new pattern (projected on the line between the two patterns' fitted images)
   says where in the exposure the new light began, ``latency = t + exposure/2 - shown_b - f * exposure``;
3. the latency is their median, its spread their robust standard deviation (the scan-out phase, the
   clocks' jitter), its uncertainty the spread over the root of their count.

A frame that does not straddle a switch only bounds the latency (it saw one pattern), so a sequence whose
switches all fall between exposures (a pattern shown just after a frame and held past the next, as the live
``--record`` does) cannot tell the latency: fewer than :data:`MIN_STRADDLES` straddling frames is a refusal,
not a guess. The camera response is taken as linear in the light (a mix of lights is the mix of images), as
the calibration's own photometric fit assumes.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from feelium.touch.settle import exposure_shares

MIN_STRADDLES = 3  # camera frames integrating one pattern switch each, fewer cannot tell (nor give a spread)
MAX_LATENCY_S = 1.0  # the search's range: the setting's own ([touch] projector_latency_s <= 1 s)
COARSE_STEP_S = 0.002  # the grid, then refined around its best at FINE_STEP_S
FINE_STEP_S = 0.0001
AMBIGUOUS_RATIO = 2.0  # the best latency's residual against the best one more than an exposure away (simulator: 190-2800)
SHARE_EDGE = 0.05  # a frame counts as straddling when both patterns have at least this share of its exposure
GRID_PX = 48  # the coarse grid's width over the sensitive patch (height kept in proportion)
MIN_STEP_DN = 2.0  # two patterns whose coarse images differ by less (RMS, DN) cannot time their switch


class LatencyError(ValueError):
    """The recording cannot tell the latency (the message says why and what sequence would)."""


@dataclass(frozen=True)
class LatencyEstimate:
    """The measured projector latency (s) from the daemon's frame clock to light in the camera."""

    latency_s: float  # median of the straddling frames' estimates
    spread_s: float  # their robust standard deviation (1.4826 MAD)
    uncertainty_s: float  # of the latency: spread over the root of the count, at least the fine grid's step
    straddles: int  # camera frames that integrated one switch each
    switches: int  # pattern switches in the projector stream
    exposure_s: float  # the exposure it was measured with
    exposure_from: str  # "recording meta" or "config"

    def summary(self) -> dict[str, object]:
        """For the calibration's JSON summary: milliseconds, rounded as the other figures."""
        return {
            "measured": True,
            "latency_ms": round(self.latency_s * 1e3, 2),
            "spread_ms": round(self.spread_s * 1e3, 2),
            "uncertainty_ms": round(self.uncertainty_s * 1e3, 2),
            "straddling_frames": self.straddles,
            "switches": self.switches,
            "exposure_ms": round(self.exposure_s * 1e3, 2),
            "exposure_from": self.exposure_from,
        }


def coarse_frame(image: np.ndarray, roi: tuple[int, int, int, int] | None) -> np.ndarray:
    """The camera frame's sensitive patch averaged down to the coarse grid, flat float64."""
    x, y, w, h = roi if roi is not None else (0, 0, image.shape[1], image.shape[0])
    patch = image[y : y + h, x : x + w]
    size = (GRID_PX, max(1, round(GRID_PX * h / w)))
    return cv2.resize(patch.astype(np.float32), size, interpolation=cv2.INTER_AREA).astype(np.float64).ravel()


def measure_latency(
    starts: np.ndarray, times: np.ndarray, frames: np.ndarray, exposure_s: float, exposure_from: str = "config"
) -> LatencyEstimate:
    """The latency from pattern switch times ``starts`` (each distinct projector frame's display time, increasing),
    camera frame times ``times`` and their coarse frames ``frames`` (one row each, :func:`coarse_frame`).

    Raises :class:`LatencyError` when the sequence has too few switches seen mid-exposure to tell."""
    switches = len(starts) - 1
    if exposure_s <= 0.0:
        raise LatencyError("the camera exposure is 0: no frame mixes two patterns, the latency cannot be measured")
    if switches < MIN_STRADDLES:
        raise LatencyError(
            f"the projector stream has {switches} pattern switch(es); measuring the latency needs at least "
            f"{MIN_STRADDLES} seen by a camera exposure"
        )
    shown = [float(s) for s in starts]
    gram = frames @ frames.T  # the residual of every latency from one K x K product (frames are few, pixels many)
    total = float(np.trace(gram))

    def residual(latency: float) -> float:
        weights = _weights(shown, times, exposure_s, latency)
        q, _ = np.linalg.qr(weights[:, weights.any(axis=0)])
        return total - float(np.einsum("ki,kl,li->", q, gram, q))

    coarse = np.arange(0.0, MAX_LATENCY_S + COARSE_STEP_S / 2, COARSE_STEP_S)
    residuals = np.asarray([residual(float(v)) for v in coarse])
    best = float(coarse[int(np.argmin(residuals))])
    if best >= MAX_LATENCY_S - COARSE_STEP_S / 2:
        raise LatencyError(
            f"the frames are best explained at the search's end ({MAX_LATENCY_S * 1e3:.0f} ms): the latency is longer "
            "than it looks for, or the camera's times are not the projector stream's clock"
        )
    # Free per-pattern images let a latency a few patterns off explain the frames too, only worse (a sequence of
    # similar holds aliases): the best must clearly beat every latency more than an exposure away from it.
    far = np.abs(coarse - best) > exposure_s + COARSE_STEP_S
    runner_up = float(residuals[far].min()) if far.any() else np.inf
    if runner_up < AMBIGUOUS_RATIO * float(residuals.min()):
        other = float(coarse[far][int(np.argmin(residuals[far]))])
        raise LatencyError(
            f"the frames fit {best * 1e3:.0f} ms and {other * 1e3:.0f} ms about as well (residuals within a factor "
            f"{AMBIGUOUS_RATIO:g}): the sequence cannot tell them apart; hold the patterns for unequal times"
        )
    fine = np.arange(max(0.0, best - COARSE_STEP_S), best + COARSE_STEP_S + FINE_STEP_S / 2, FINE_STEP_S)
    best = float(fine[int(np.argmin([residual(float(v)) for v in fine]))])
    estimates = _straddle_estimates(shown, times, frames, exposure_s, best)
    if len(estimates) < MIN_STRADDLES:
        raise LatencyError(
            f"only {len(estimates)} camera frame(s) integrated a switch between two patterns each also seen alone "
            f"({switches} switches, {exposure_s * 1e3:.1f} ms exposure): too few to tell the latency. Hold each pattern "
            "several camera frames and let the switches fall at varied phases of the camera's frames"
        )
    values = np.asarray(estimates)
    median = float(np.median(values))
    spread = 1.4826 * float(np.median(np.abs(values - median)))
    return LatencyEstimate(
        latency_s=median,
        spread_s=spread,
        uncertainty_s=max(1.2533 * spread / float(np.sqrt(len(values))), FINE_STEP_S),  # the median's standard error
        straddles=len(values),
        switches=switches,
        exposure_s=exposure_s,
        exposure_from=exposure_from,
    )


def _weights(shown: list[float], times: np.ndarray, exposure_s: float, latency_s: float) -> np.ndarray:
    """(frames, patterns): each camera frame's exposure shares at ``latency_s``, as the touch path mixes them."""
    weights = np.zeros((len(times), len(shown)))
    for k, t in enumerate(times):
        for i, w in exposure_shares(shown, float(t), exposure_s, latency_s):
            weights[k, i] = w
    return weights


def _straddle_estimates(
    shown: list[float], times: np.ndarray, frames: np.ndarray, exposure_s: float, latency_s: float
) -> list[float]:
    """Each straddling frame's own latency, from its observed share of the new pattern (module docstring, 2)."""
    weights = _weights(shown, times, exposure_s, latency_s)
    seen = weights.any(axis=0)
    images = np.zeros((len(shown), frames.shape[1]))
    images[seen] = np.linalg.lstsq(weights[:, seen], frames, rcond=None)[0]
    # A pattern's image is known apart from the mixes only when some frame saw it alone: without that the fit
    # can explain a frame by any share (a pattern held one camera frame is a free image), and a share that
    # cannot be wrong says nothing, so such a straddle does not count.
    alone = (weights >= 1.0 - 1e-9).sum(axis=0)
    out = []
    for k, t in enumerate(times):
        parts = np.flatnonzero(weights[k] > 0.0)
        if len(parts) != 2 or weights[k, parts].min() < SHARE_EDGE or alone[parts].min() < 1:
            continue
        a, b = images[parts[0]], images[parts[1]]
        step = b - a
        norm = float(step @ step)
        if norm < MIN_STEP_DN**2 * step.size:
            continue  # two patterns the camera hardly tells apart say little of when one replaced the other
        share = float((frames[k] - a) @ step) / norm
        if 0.0 < share < 1.0:
            out.append(float(t) + exposure_s / 2.0 - shown[parts[1]] - share * exposure_s)
    return out
