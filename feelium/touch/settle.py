"""How far the projected-light prediction can be off, per pixel, and what the pipeline does about it.

The daemon knows which projector frames were lit during a camera exposure only
as well as it knows the projector's latency: projector frame ``k`` lights the
membrane over ``[k / fps + latency, (k + 1) / fps + latency)`` and the camera
integrates what overlaps its exposure. Within a scene the frames hardly differ
and a latency error changes nothing; at a scene cut the exposure that straddles
it mixes the two scenes in proportions the latency decides, and an error of a
few milliseconds leaves a few per cent of the old face's edges in the
prediction, as sharp as a fingertip's shadow.

So the prediction comes with its *spread*: per pixel, how far the predicted
light moves when the latency is moved by its uncertainty either way
(:func:`predicted_exposure`). It is zero inside a scene, small during a fade
(the light changes smoothly) and large only on the one or two camera frames
that straddle a cut, and only where the two scenes differ. The pipeline takes
every shadow at the smallest depth the prediction allows (depth minus the
spread's share of the reference, :func:`depth_uncertainty`), so an error
within the spread cannot make a shadow, while a press where the prediction is
sure (most of a cut's frame, every frame of a fade) is seen at once; and a
pixel whose uncertainty reaches the darkening floor teaches the reference and
the photometric response nothing.

This replaces a global rule (a frame whose mean predicted light changed by more
than 0.04 held every new touch for 0.25 s after it): with a cut every few
seconds it blinded the whole membrane for about a quarter of the time and
missed every tap that fell in it, to guard against errors that are local and
bounded.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections.abc import Callable, Hashable, Sequence

import cv2
import numpy as np

from feelium.skin.blurwindow import Window, blur_window
from feelium.touch.buffers import Scratch


def exposure_shares(
    shown: Sequence[float], t: float, exposure_s: float, latency_s: float
) -> list[tuple[int, float]]:
    """Indices into ``shown`` (the times frames were handed to the projector, increasing) lit during the camera
    exposure centred on ``t``, with their share of it.

    Frame ``i`` lights the membrane over ``[shown[i] + latency, shown[i + 1] + latency)``, the newest one until
    further notice and the oldest one from any earlier time (the best guess of what was shown before); light
    adds linearly, so the camera integrates each in proportion to its overlap with the exposure. A zero
    exposure takes the frame lit at ``t``.
    """
    if not shown:
        raise ValueError("no projector frame to mix")
    start = t - exposure_s / 2.0 - latency_s
    end = start + exposure_s
    n = len(shown)
    if exposure_s <= 0.0:  # the frame lit at ``start``: the last one shown at or before it, else the oldest
        return [(max(bisect_right(shown, start) - 1, 0), 1.0)]
    # Only frames from the last one shown at or before ``start`` to the last one shown before ``end`` can overlap
    # (any other frame's span ends by ``start`` or begins at ``end`` or later); each is weighed as before, the same
    # arithmetic, without walking the whole history (four mixes a camera frame, ~75 Python calls on 6-8 frames).
    out = []
    for i in range(max(bisect_right(shown, start) - 1, 0), max(bisect_left(shown, end), 1)):
        lo = -np.inf if i == 0 else shown[i]
        hi = np.inf if i + 1 == n else shown[i + 1]
        overlap = min(end, hi) - max(start, lo)
        if overlap > 0.0:
            out.append((i, overlap / exposure_s))
    return out


def predicted_exposure(
    frames: Sequence[tuple[float, Hashable]],
    light_of: Callable[[Hashable], np.ndarray],
    t: float,
    *,
    exposure_s: float,
    latency_s: float,
    latency_sigma_s: float,
    scratch: Scratch | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(light, spread) for the camera exposure centred on ``t``.

    ``frames``: (time shown, key) of the projector frames around ``t``, in time order; ``light_of(key)`` is a
    frame's predicted light (camera frame size, float32). ``light`` is the exposure-weighted mix at the assumed
    ``latency_s``; ``spread`` the largest absolute change of that mix when the latency is ``latency_s +-
    latency_sigma_s`` (light adds linearly, so each is the same weighted sum). With ``scratch`` (once per camera
    frame, :mod:`feelium.touch.buffers`) both results are its buffers, valid until the next call.
    """
    shown = [f[0] for f in frames]
    buf = Scratch() if scratch is None else scratch

    def mix(latency: float, name: str) -> np.ndarray:
        out: np.ndarray | None = None
        for i, w in exposure_shares(shown, t, exposure_s, latency):
            light = light_of(frames[i][1])
            dtype = np.promote_types(light.dtype, np.float32)  # np.result_type's answer for an array, undispatched
            if out is None:
                out = np.multiply(light, np.float32(w), out=buf.get(name, light.shape, dtype))
            else:
                cv2.scaleAdd(light.astype(dtype, copy=False), float(w), out, dst=out)  # out += w * light, one pass
        assert out is not None
        return out

    light = mix(latency_s, "exposure.light")
    spread = buf.like("exposure.spread", light)
    if latency_sigma_s <= 0.0:
        spread.fill(0)
        return light, spread
    cv2.absdiff(mix(latency_s - latency_sigma_s, "exposure.other"), light, dst=spread)
    other = mix(latency_s + latency_sigma_s, "exposure.other")
    cv2.absdiff(other, light, dst=other)
    cv2.max(spread, other, dst=spread)
    return light, spread


def depth_uncertainty(
    spread: np.ndarray,
    slope: np.ndarray,
    expected: np.ndarray,
    sigma: float,
    scratch: Scratch | None = None,
    window: Window | None = None,
) -> np.ndarray:
    """Per working pixel, the largest smoothed depth a prediction error within ``spread`` can fake.

    An error ``e`` of the predicted light moves the compensated frame by ``slope * e`` (the pixel's gain for
    projected light), so its depth by ``slope * e / expected`` (``expected``: the reference times the exposure
    gain, floored by the caller). The depth map is smoothed by a Gaussian of ``sigma`` before any decision, and
    ``|G * x| <= G * |x|``, so the same smoothing of the bound bounds the smoothed error. With ``scratch`` the
    result is one of its buffers (valid until its next use). ``window`` (:func:`spread_window`): compute only there
    (``expected`` need be valid only there) and return the bound over it; outside it the bound is zero.
    """
    buf = Scratch() if scratch is None else scratch
    window = window if window is not None else (slice(None), slice(None))
    dtype = np.result_type(spread, slope, expected)
    # Views of whole-size buffers: the window moves every frame, and a buffer per shape would be a new allocation.
    full = buf.get("uncertainty.bound", spread.shape, dtype)
    bound = full[window]
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        np.multiply(spread[window], slope[window], out=bound)
        np.divide(bound, expected[window], out=bound)
    if not cv2.checkRange(bound)[0]:  # one pass; finite inputs (the pipeline cleans them) give a finite bound
        np.nan_to_num(bound, copy=False, nan=0.0, posinf=1.0, neginf=0.0)
    bound.clip(0.0, 1.0, out=bound)
    if sigma > 0.2:
        smooth = buf.like("uncertainty.smooth", full)[window]
        bound = cv2.GaussianBlur(bound, (0, 0), sigma, dst=smooth, borderType=cv2.BORDER_REPLICATE)
    return bound


def spread_window(spread: np.ndarray, sigma: float, scratch: Scratch | None = None) -> Window | None:
    """The window of a working image where :func:`depth_uncertainty` (blurred by ``sigma``) can be nonzero, or None
    when the spread is zero everywhere (every frame inside a scene: the bound is then zero).

    Zero spread gives an exactly zero bound (``0 * slope / expected``, NaN and inf cleaned to 0), and the blur of
    zeros is zero, so outside the window the bound is 0 to the bit; inside it the window's blur gives the whole
    image's bits (:mod:`feelium.skin.blurwindow`).
    """
    buf = Scratch() if scratch is None else scratch
    nonzero = np.not_equal(spread, 0.0, out=buf.like("uncertainty.nonzero", spread, bool))  # NaN counts
    x, y, w, h = cv2.boundingRect(nonzero.view(np.uint8))
    if w == 0 or h == 0:
        return None
    rows, cols = spread.shape
    return blur_window((cols, rows), (x, y, w, h), sigma if sigma > 0.2 else 0.0)
