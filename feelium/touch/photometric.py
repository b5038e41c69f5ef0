"""What projected light does to the camera, per pixel, learned online from frames without hands.

The projector is the membrane's back-light, but not all of the light the rear
camera sees comes from it: room light coming in through the membrane does not
follow what the projector shows. Per pixel the camera sees

    frame = a * light + c

where ``light`` is the predicted projector light relative to the flat grey
(the calibration's map, gamma and blur, mixed over the camera's exposure),
``a`` the pixel's gain for projected light and ``c`` what does not follow the
projector (room light, the projector's black). Dividing a frame by ``light``
(the multiplicative model) over-corrects wherever ``c`` matters: a dark mouth
turns the room light behind it into a deep "shadow".

The compensation adds back exactly the projected light the flat grey would have
given, ``frame + a * (1 - light)``, so a shadow is measured as the share of the
*flat* membrane's light it takes away, the same scale the reference and the
gates were calibrated on. Only ``a`` is needed for that, and ``a`` is the slope
of frame against light: a per-pixel least-squares fit over exponentially
weighted sums, pulled towards the pixel's own ``mean(frame) / mean(light)``
(the multiplicative model, ``c = 0``) by ``prior_var`` where it has seen too
little change of light to tell the two apart.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from feelium.touch.buffers import Scratch
from feelium.touch.median import median
from feelium.touch.roomshare import MIN_LIGHT_VAR

LIGHT_MIN = 0.05  # predicted light (relative to flat) below which frame / light says nothing
LIGHT_MAX = 16.0  # predicted light above which a prediction is not believed
FRAME_MAX = 1e4  # grey levels (any camera depth, any working dtype) above which a value is not a frame
SHARE_SAMPLE_STEP = 4
MIN_INFORMATIVE = 50  # pixels whose light varied, needed to pool the projector's share
SHARE_LIMITS = (0.05, 1.0)
INITIAL_SHARE = 0.5  # the projector's share of the light assumed before it is learned
# How often the slope is solved from the sums once the share is known (s). The sums take every hand-free frame;
# the solve (a dozen passes over the image and a median) is most of the learning's cost and the response it solves
# for moves with a time constant of ``tau_s`` (20 s): in 0.2 s the sums give 1 % of their weight to new frames, so a
# solve every frame moved the slope by about a hundredth of what 0.2 s of frames can teach.
FIT_INTERVAL_S = 0.2


class ProjectorResponse:
    """Per-pixel slope ``a`` of camera value against predicted projected light, learned online."""

    def __init__(self, *, tau_s: float, prior_var: float) -> None:
        self.tau_s = tau_s
        self.prior_var = prior_var
        self.slope: np.ndarray | None = None
        self.updates = 0
        self.share: float | None = None  # projector's share of a pixel's light under flat grey, once learned
        self._sums: list[np.ndarray] | None = None  # weights, light, light^2, frame, frame * light
        self._last_t: float | None = None
        self._last_fit_t: float | None = None
        self._fit_due = False  # a caller saw the light change: solve on the next learned frame
        self.fits = 0
        self._scratch = Scratch()  # learn's and the fit's per-frame temporaries: it runs on every hand-free frame

    def reset(self) -> None:
        self.slope = None
        self.updates = 0
        self.share = None
        self._sums = None
        self._last_t = None
        self._last_fit_t = None
        self._fit_due = False

    def request_fit(self) -> None:
        """Solve on the next :meth:`learn`, whatever the interval: the caller saw the membrane's light change (a lamp,
        an exposure step), which is when the projector's share of the light can move."""
        self._fit_due = True

    def compensate(self, frame: np.ndarray, light: np.ndarray) -> np.ndarray:
        """``frame + a * (1 - light)``: the frame as the flat grey would have lit it (one reused buffer, valid
        until the next call).

        Before anything was learned the projector's share is taken as :data:`INITIAL_SHARE`, which keeps the
        slope within twice the frame even where the prediction is near black (``frame / light``, the
        multiplicative model, would multiply a black pixel's room light by 25).
        """
        if self.slope is None:
            share = np.float32(INITIAL_SHARE)
            slope = share * frame / (share * np.maximum(light, np.float32(0.0)) + (np.float32(1.0) - share))
            self.slope = np.nan_to_num(slope, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
        buf = self._scratch
        part = buf.like("compensate.part", light, np.result_type(np.float32, light))
        np.subtract(np.float32(1.0), light, out=part)
        part *= self.slope
        shape = frame.shape if frame.shape == part.shape else np.broadcast_shapes(frame.shape, part.shape)  # 2 us less
        return np.add(frame, part, out=buf.get("compensated", shape, np.result_type(frame, part)))

    def learn(self, t: float, frame: np.ndarray, light: np.ndarray, usable: np.ndarray) -> np.ndarray | None:
        """Add one hand-free frame (``usable``: unshadowed, unsaturated, finite pixels) to the sums; solve the slope
        when it is due.

        The solve is due on every frame until the projector's share is known (nothing is settled before), then
        every :data:`FIT_INTERVAL_S` of frame time, and on the first frame after :meth:`request_fit`.

        Returns how much the solve moved each pixel's slope (new minus old; a scratch image valid until the next
        call), or None when no solve ran: the compensation of every later frame moves by it times ``1 - light``,
        and whatever was built on the old compensation (the reference) must move with it.
        """
        # Values outside what a camera and a prediction can give (NaN, inf, negative, absurdly large) teach nothing.
        buf = self._scratch
        # One pass each proves the usual case, every value in range (the pipeline cleans the light, a camera gives
        # finite values), and then masking is a product with the 0/1 weights; else each pixel is checked.
        in_range = bool(cv2.checkRange(frame, True, 0.0, FRAME_MAX)[0]) and bool(
            cv2.checkRange(light, True, 0.0, LIGHT_MAX)[0]
        )
        if not in_range:
            check = buf.like("learn.check", usable)
            usable = np.logical_and(usable, np.greater_equal(frame, 0.0, out=check), out=buf.like("learn.usable", usable))
            usable &= np.less_equal(frame, FRAME_MAX, out=check)
            usable &= np.greater_equal(light, 0.0, out=check)
            usable &= np.less_equal(light, LIGHT_MAX, out=check)
        if not usable.any():
            return None
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        self._last_t = t
        keep = np.float32(math.exp(-dt / self.tau_s))
        w = buf.like("learn.w", usable, np.float32)
        np.copyto(w, usable)
        if self.slope is None:
            self.compensate(frame, light)
        f = buf.like("learn.f", usable, np.float32)
        x = buf.like("learn.x", usable, np.float32)
        if in_range:  # finite and >= 0: a product with 0 or 1 is the value or +0, exactly as the copy below
            np.multiply(frame, w, out=f)
            np.multiply(light, w, out=x)
        else:
            f.fill(0.0)
            np.copyto(f, frame, where=usable)
            x.fill(0.0)
            np.copyto(x, light, where=usable)
        xx = np.multiply(x, x, out=buf.like("learn.xx", x))
        fresh = [w, x, xx, f, np.multiply(f, x, out=buf.like("learn.fx", x))]
        if self._sums is None:
            self._sums = [a.copy() for a in fresh]  # kept across frames: never a scratch buffer
        else:
            for total, add in zip(self._sums, fresh):
                cv2.scaleAdd(total, float(keep), add, dst=total)  # total * keep + add in one pass
        self.updates += 1
        due = self._last_fit_t is None or t - self._last_fit_t >= FIT_INTERVAL_S - 1e-6  # 6 / 30 s is 0.2 s too
        if not (self.share is None or self._fit_due or due):
            return None
        moved = self._fit()
        self.fits += 1
        self._last_fit_t, self._fit_due = t, False
        return moved

    def _fit(self) -> np.ndarray:
        """Ridge slope per pixel: (cov(light, frame) + prior_var * prior) / (var(light) + prior_var).

        The prior is what the pixel's mean says under the projector's share of the light, ``share``, pooled
        (median) over the pixels that have seen the light change: ``a = share * mean(frame) /
        (share * mean(light) + 1 - share)``. Pooling matters where the face stays dark: there
        ``mean(frame) / mean(light)`` (share = 1, the multiplicative model) would multiply every small
        prediction error by the room light over the projector's black. Pixels never seen keep their slope.
        Returns each pixel's change of slope (0 where unseen), in the fit's last scratch image.
        """
        assert self._sums is not None and self.slope is not None
        n, sx, sxx, sf, sfx = self._sums
        buf = self._scratch  # each line's arithmetic in the same order as written out in the docstring
        # Only :meth:`learn` calls this, after its frame's terms went into the sums: its buffers are free again,
        # so the fit writes into them (six working images fewer held, 0.2 MB each at 320x240).
        seen = np.greater(n, np.float32(1e-3), out=buf.like("learn.check", n, bool))
        n = np.maximum(n, np.float32(1e-3), out=buf.like("learn.w", n))
        mx = np.divide(sx, n, out=buf.like("learn.x", n))
        mf = np.divide(sf, n, out=buf.like("learn.f", n))
        tmp = buf.like("learn.xx", n)
        var = np.divide(sxx, n, out=buf.like("learn.fx", n))
        var -= np.multiply(mx, mx, out=tmp)
        np.maximum(var, np.float32(0.0), out=var)
        cov = np.divide(sfx, n, out=buf.like("compensate.part", n))  # compensate()'s temporary: free here too
        cov -= np.multiply(mx, mf, out=tmp)
        self.share = self._pooled_share(var, cov, mx, mf, seen)
        share = np.float32(INITIAL_SHARE if self.share is None else self.share)
        prior = np.multiply(share, mf, out=buf.like("fit.prior", n))
        under = np.multiply(share, mx, out=tmp)
        under += np.float32(1.0) - share
        prior /= np.maximum(under, np.float32(LIGHT_MIN), out=under)
        prior *= np.float32(self.prior_var)
        slope = np.add(cov, prior, out=cov)
        slope /= np.add(var, np.float32(self.prior_var), out=var)
        if not cv2.checkRange(slope)[0]:  # one pass proves the usual all-finite case; nan_to_num takes six
            np.nan_to_num(slope, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
        moved = np.subtract(slope, self.slope, out=tmp)  # ``under``'s buffer: free once the slope is solved
        moved *= seen  # unseen pixels keep their slope: no change
        np.copyto(self.slope, slope, where=seen)
        return moved

    def _pooled_share(
        self, var: np.ndarray, cov: np.ndarray, mx: np.ndarray, mf: np.ndarray, seen: np.ndarray
    ) -> float | None:
        """Median share of projected light ``a / (a + c)`` over pixels whose light varied (else the last one)."""
        k = SHARE_SAMPLE_STEP  # a median over every k-th pixel in both directions is as good and k^2 cheaper
        var, cov, mx, mf = var[::k, ::k], cov[::k, ::k], mx[::k, ::k], mf[::k, ::k]
        seen = seen[::k, ::k]
        informative = seen & (var > np.float32(self.prior_var))
        if np.count_nonzero(informative) < MIN_INFORMATIVE:
            # A static skin's light varies only by the probe's few percent (feelium.skin.probe), far under the
            # prior's variance: no pixel ever outweighs its prior, and without a share nothing settled, so the
            # projector's share was never learned either (a blimp compensating a still avatar never raised a
            # touch). A median over many pixels needs no single pixel to outweigh its prior: it takes those that
            # saw the probe (the variance at which the share per place is believed, roomshare.MIN_LIGHT_VAR).
            informative = seen & (var > np.float32(MIN_LIGHT_VAR))
            if np.count_nonzero(informative) < MIN_INFORMATIVE:
                return self.share
        a = cov[informative] / var[informative]
        flat = mf[informative] + a * (np.float32(1.0) - mx[informative])  # a + c: the value under flat grey
        ok = np.isfinite(a) & np.isfinite(flat) & (flat > 0.0)
        if np.count_nonzero(ok) < MIN_INFORMATIVE:
            return self.share
        ratio = a[ok] / flat[ok]  # finite over positive: never NaN
        pooled = ratio.dtype.type(median(ratio))  # np.median's value, in its dtype, without its dispatch
        low, high = (ratio.dtype.type(limit) for limit in SHARE_LIMITS)
        return float(min(max(pooled, low), high))  # np.clip's, the bounds in the values' dtype as it takes them
