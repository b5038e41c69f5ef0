"""The adaptive reference: what the untouched, back-lit membrane looks like now.

Relative shadow depth is only as good as this image. It must follow slow
changes (projector warm-up, exposure drift, a new projected face) but never
learn a shadow that is present, or a 30 s palm press would fade away. So:

- a global exposure gain is measured every frame as the median ratio
  frame / reference over unshadowed pixels; drift becomes gain, not shadow;
- where no shadow is seen, the reference follows the gain-normalised frame with
  an exponential average whose rate comes from the camera time step (gaps and
  jitter are handled by construction); where the membrane got brighter it
  follows faster, because a shadow cannot brighten (only beyond a noise
  margin: a faster update on every noisy upward pixel would bias the reference
  up, the gain down, and the two would run away together);
- under a shadow it does not move, except a much slower forced update where the
  shadow is not anchored (so a stray dark patch cannot freeze it forever);
- a jump of the gain between frames is a lighting step: the reference is
  re-baselined to the new frame outside shadows (inside, it is the old
  reference times the new gain), and gain returns to 1, without any event.

The reference is floored at a tiny positive value so a long run of black
frames decays to the floor, never into denormals.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from feelium.touch.buffers import Scratch
from feelium.touch.median import median

REFERENCE_FLOOR = 1.0 / 64.0  # grey levels; far below the dark mask, far above denormals
GAIN_LIMITS = (1e-3, 1e3)


class AdaptiveReference:
    """Reference image plus exposure gain, updated from frames and shadow masks."""

    def __init__(
        self,
        *,
        tau_s: float,
        bright_tau_s: float,
        forced_tau_s: float,
        dark_level: float,
        saturation_level: float,
        rebaseline_step: float,
        sample_step: int,
        bright_margin: float = 0.07,
        row_clip: float = 0.0,
    ) -> None:
        self.tau_s = tau_s
        self.bright_tau_s = bright_tau_s
        self.forced_tau_s = forced_tau_s
        self.dark_level = dark_level
        self.saturation_level = saturation_level
        self.rebaseline_step = rebaseline_step
        self.sample_step = sample_step
        self.bright_margin = bright_margin
        self.row_clip = row_clip
        self.rows: np.ndarray | None = None
        self.image: np.ndarray | None = None
        self.gain = 1.0
        self.last_t: float | None = None
        self.rebaselines = 0
        self._rate_cache: tuple[float, tuple[float, float, float]] | None = None
        self._scratch = Scratch()  # per-frame temporaries of measure_rows and update (never the image itself)

    def reset(self) -> None:
        self.image = None
        self.gain = 1.0
        self.rows = None
        self.last_t = None

    def initialise(self, t: float, frame: np.ndarray) -> None:
        """Take ``frame`` as the untouched membrane."""
        self.image = np.maximum(frame, REFERENCE_FLOOR).astype(frame.dtype)
        self._bright_factor = frame.dtype.type(1.0 + self.bright_margin)
        self._floor = frame.dtype.type(REFERENCE_FLOOR)
        self.updates = 0
        self.gain = 1.0
        self.last_t = t

    def measure_gain(self, frame: np.ndarray, shadow: np.ndarray | None, usable: np.ndarray | None = None) -> float:
        """Robust exposure gain: median of frame / reference over usable, unshadowed pixels.

        Keeps the previous gain when too few pixels are usable (all dark, all
        saturated, all shadowed), so nothing degenerate can come out. ``usable``: those pixels at full size when
        the caller has them (the reference times the gain at least ``dark_level``, the frame under
        ``saturation_level``, off ``shadow``): the same mask, sampled here, without making it again.
        """
        assert self.image is not None
        s = self.sample_step
        f = frame[::s, ::s]
        r = self.image[::s, ::s]
        if usable is not None:
            usable = usable[::s, ::s]
        else:
            usable = (r * self.gain >= self.dark_level) & (f < self.saturation_level)
            if shadow is not None:
                usable &= ~shadow[::s, ::s]
        if np.count_nonzero(usable) < max(8, usable.size // 50):
            return self.gain
        ratio = median(f[usable] / r[usable])
        if not math.isfinite(ratio):
            return self.gain
        return min(max(ratio, GAIN_LIMITS[0]), GAIN_LIMITS[1])

    def observe_gain(self, gain: float, frame: np.ndarray, shadow: np.ndarray | None) -> bool:
        """Adopt this frame's gain; on a lighting step, re-baseline. Returns True when it re-baselined."""
        assert self.image is not None
        step = abs(gain / self.gain - 1.0)
        if step <= self.rebaseline_step:
            self.gain = gain
            return False
        # Lighting step: outside shadows the frame is the new truth; inside, scale the old reference.
        scaled = self.image * self.dtype_cast(gain)
        if shadow is not None and shadow.any():
            np.copyto(scaled, frame, where=~shadow)
        else:
            scaled = frame.astype(self.image.dtype, copy=True)
        np.maximum(scaled, REFERENCE_FLOOR, out=scaled)
        self.image = scaled
        self.gain = 1.0
        self.rebaselines += 1
        return True

    def measure_rows(self, frame: np.ndarray, exclude: np.ndarray | None) -> np.ndarray | None:
        """Per-row gain relative to the global gain, (H, 1), or None when disabled.

        A laser-scanning projector beating with a rolling-shutter camera puts
        faint horizontal bands on the membrane that crawl from frame to frame;
        measured per row they are divided out like exposure instead of looking
        like shadows. Each row's gain is the mean of frame / expected over its
        usable pixels with every ratio clipped to ``1 +- row_clip``, so a
        shadow that arrived this frame pulls its rows by at most that much;
        rows with nothing usable keep the global gain. ``exclude`` should be
        only the deep shadows: excluding every faintly darkened pixel would let
        a dark band mask itself out and persist.
        """
        assert self.image is not None
        c = self.row_clip
        if c <= 0.0:
            self.rows = None
            return None
        one = self.dtype_cast(1.0)
        buf = self._scratch
        ratio = np.divide(frame, self.image, out=buf.get("rows.ratio", frame.shape, np.result_type(frame, self.image)))
        ratio *= self.dtype_cast(1.0 / self.gain)
        ratio.clip(one - self.dtype_cast(c), one + self.dtype_cast(c), out=ratio)
        dark = self.dtype_cast(self.dark_level / self.gain)
        usable = np.greater_equal(self.image, dark, out=buf.like("rows.usable", frame, bool))
        other = np.less(frame, self.saturation_level, out=buf.like("rows.other", frame, bool))
        usable &= other
        if exclude is not None:
            usable &= np.logical_not(exclude, out=other)
        np.logical_not(usable, out=usable)
        np.copyto(ratio, one, where=usable)
        rows = ratio.mean(axis=1, keepdims=True, dtype=self.image.dtype)
        self.rows = rows
        return rows

    def expected_gain(self) -> float | np.ndarray:
        """What multiplies the reference to predict this frame: global gain, times row gains if any."""
        if self.rows is None:
            return self.gain
        return self.rows * self.dtype_cast(self.gain)

    def dtype_cast(self, value: float) -> np.floating:
        assert self.image is not None
        return self.image.dtype.type(value)

    def update(self, t: float, frame: np.ndarray, shadow: np.ndarray, anchored: np.ndarray | None) -> None:
        """Move the reference towards ``frame / gain``.

        ``shadow``: bool mask of darkened pixels (frozen unless not anchored);
        ``anchored``: bool mask of pixels under anchored contacts (never updated), or None.
        """
        assert self.image is not None and self.last_t is not None
        dt = t - self.last_t
        self.last_t = t
        if dt <= 0.0:
            return
        alpha, extra, alpha_forced = self._rates(dt)
        self.updates += 1
        if self.updates * alpha < 1.0:
            # Warm-up: a plain running mean of the first frames, so the reference
            # starts as an average, not as one noisy frame.
            alpha = 1.0 / (self.updates + 1)
        scale = self.expected_gain()
        buf = self._scratch
        image = self.image
        if self.rows is not None or self.gain != 1.0:
            target = np.divide(frame, scale, out=buf.get("update.target", frame.shape, np.result_type(frame, scale)))
        else:
            target = frame
        any_shadow = bool(shadow.any())
        free = np.logical_not(shadow, out=buf.like("update.free", shadow)) if any_shadow else None
        cv2.accumulateWeighted(target, image, alpha, mask=None if free is None else free.view(np.uint8))
        if extra > 0.0:
            # Second step so the total rate where it got clearly brighter equals the bright rate.
            bright = np.multiply(image, self._bright_factor, out=buf.like("update.bright", image))
            shape = bright.shape if target.shape == bright.shape else np.broadcast_shapes(target.shape, bright.shape)
            brighter = np.greater(target, bright, out=buf.get("update.brighter", shape, bool))
            if free is not None:
                brighter &= free
            cv2.accumulateWeighted(target, image, extra, mask=brighter.view(np.uint8))
        if any_shadow:
            if anchored is None:
                forced = shadow
            else:
                forced = np.logical_not(anchored, out=buf.like("update.forced", shadow))
                forced &= shadow
            cv2.accumulateWeighted(target, image, alpha_forced, mask=forced.view(np.uint8))
        np.maximum(image, self._floor, out=image)

    def carry(self, change: np.ndarray) -> None:
        """The frames' compensation moved by ``change`` (working size, frame units: a new slope of the projector's
        response times ``1 - light``); move the image with it, shadows included, so the next frame is compared
        with what the membrane looks like under the new compensation, not read as a shadow or a brightening
        until the reference has followed (seconds, and never under a shadow)."""
        assert self.image is not None
        step = np.divide(change, self.expected_gain(), out=self._scratch.like("carry.step", self.image))
        self.image += step
        np.maximum(self.image, self._floor, out=self.image)

    def hold(self, t: float) -> None:
        """Skip this frame (its prediction is uncertain): nothing is learned, the clock moves on."""
        self.last_t = t

    def _rates(self, dt: float) -> tuple[float, float, float]:
        """Per-update blend factors for a time step (cached: frame intervals repeat)."""
        cached = self._rate_cache
        if cached is not None and cached[0] == dt:
            return cached[1]
        alpha = 1.0 - math.exp(-dt / self.tau_s)
        alpha_bright = 1.0 - math.exp(-dt / self.bright_tau_s)
        extra = 1.0 - (1.0 - alpha_bright) / (1.0 - alpha) if alpha_bright > alpha and alpha < 1.0 else 0.0
        rates = (alpha, extra, 1.0 - math.exp(-dt / self.forced_tau_s))
        self._rate_cache = (dt, rates)
        return rates
