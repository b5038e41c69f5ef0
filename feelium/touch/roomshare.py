"""The projector's share of the membrane's light, per place, measured in steady light from the projector's own light.

A lit room's light comes through the membrane and a hand above it blocks that
light: a close hover under a lamp casts a shadow as deep and as sharp as a
contact's, so depth and edge cannot tell them apart where the room's light is
a large share of the membrane's. What a hover cannot do is take the
*projector's* light away: that light comes from inside, and only skin pressed
on the membrane removes part of it (the frustrated reflection in the film).
So a shadow is a contact only if it is deeper than all the light a hand above
the membrane could block, which needs, per place, the share of the light that
does *not* come straight from the projector: the room's lamps and the
projector's own light returned by the room (that one follows the projector's
mean, not its pattern).

The daemon knows what it projects. Whatever it shows (the face, or a faint
slow pattern of its own, the *probe*, on a static skin), the camera's value
per pixel is ``G * (a * light + c)``: ``light`` the predicted projector light
relative to flat grey, ``a`` the projector's direct part, ``c`` everything
that does not follow the pattern, ``G`` the exposure. Divided by what the
reference expects for the flat membrane (``G * (a + c)``, the exposure gain
times the reference), the frame is

    z = 1 + p * (light - 1),        p = a / (a + c)

per pixel: the projector's share ``p`` is the slope of ``z`` against
``light - 1``, whatever the exposure and the room's level, as long as the
reference follows them. It is fitted per coarse tile (room light is smooth; a
tile of 16 x 16 working pixels, every other row of it read, averages the pixel
noise down 11 times: :data:`LEARN_ROW_STEP`) over
exponentially weighted sums of hand-free frames, with an intercept (a global
error of the exposure gain moves every tile alike and is not light), and
spread to the tiles that saw too little change of light (a tile straddling
the probe's pattern) by a normalised convolution, weighted by how much each
tile saw.

When the room's light changes (a lamp, an exposure step: the pipeline re-seeds
its reference, :mod:`feelium.touch.illumination`) the share changes at once:
the change ``frame = e * reference + added`` measured per tile scales the
projector's part by ``e`` and the whole by ``e + added / reference``, so the
sums are rescaled by their ratio and the share follows the switch in the same
frame instead of relearning for seconds. Slower changes of the room (a person
walking past the lamp, daylight) never re-seed: the reference follows them
frame by frame, and so does the share, by the same rule with ``e`` = 1 (the
projector's part, in the reference's gain-free units, does not move; any
change of a tile's reference relative to the membrane's median is the room's):
each learning step scales a tile's sums by the ratio of its normalised
reference then and now, so the share does not lag the room by its 5 s memory.
A change of the room over the whole membrane (a person's shadow sweeping it in
a second, daylight) cannot be told from the exposure by the reference: the
probe itself measures it. The same fit over a short memory
(:data:`FAST_TAU_S`, about one probe period), pooled over every tile (the
membrane's level of share, not its detail), is learned on every frame, hands
or not (from the pixels away from shadows); one factor ``k`` on the room's
light everywhere, ``p' = p / (p + k (1 - p))`` (the projector's part fixed, the
room's scaled), is solved so that the long fit's shares, moved by it, pool to
what the short fit measures: the detail from 5 s, the room's level from the
last half second. A tap under a passing person's shadow (room light
down by 70 %: the true share 0.45 -> 0.7) otherwise met a share learned before
it, and its contact looked like a hover (``projected_depth`` 0.14 < 0.2).

A re-seed also re-bases both memories (:meth:`ProjectorShare.rebase`): what the
new reference kept of the projected pattern is a new intercept per tile, not a
change of share.

Pure arrays in, arrays out; no clock.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from feelium.skin import probe
from feelium.touch.illumination import TILE_PX
from feelium.touch.median import median

MIN_TILE_WEIGHT = 0.5  # share of a tile's pixels that must be usable for it to learn on this frame
# A tile's share is believed once it has seen this variance of ``light - 1``: the probe's sinusoid gives
# ``amplitude^2 / 2`` inside a cell (0.00045 at 3 %), and a tile passes at 1 / 4.5 of it (1e-4 at 3 %, session 13's
# value): after a few frames inside a cell, never on a tile that straddles two cells about equally.
MIN_LIGHT_VAR = probe.AMPLITUDE**2 / 2.0 / 4.5
SPREAD_SIGMA_TILES = 1.0  # tiles take the share of the informative tiles about this near
SHARE_LIMITS = (0.0, 1.0)
FAST_TAU_S = 0.5  # the short memory of the membrane's level of share: one probe period
ROOM_SCALE_LIMITS = (0.1, 10.0)  # how far the room's light may have moved since the long fit (a person's shadow: 0.3)
# The tiles' sums are taken over every LEARN_ROW_STEP-th row of the working image: a tile's 16 x 16 pixels (at detect_scale 1) average
# the camera's noise far below the probe's 3 % (2 DN of noise over 128 pixels is 0.18 DN against ~3 DN of light
# change), so half the rows teach the fit what all of them did, at half the cost of the frame's passes.
LEARN_ROW_STEP = 2
NEWTON_STEPS = 8  # at most, for the room factor k: from 1 it took 4 to 8 on the lit room's frames


def tile_grid(shape: tuple[int, int], tile_px: int = TILE_PX) -> tuple[int, int]:
    """(columns, rows) of coarse tiles of ``tile_px`` pixels a side for a working image of ``shape`` (rows,
    columns)."""
    h, w = shape
    return max(1, w // tile_px), max(1, h // tile_px)


def upsampled_at(coarse: np.ndarray, shape: tuple[int, int], x: int, y: int) -> float:
    """The value at working pixel (``x``, ``y``) of ``coarse`` bilinearly upsampled to ``shape`` (rows, columns) as
    ``cv2.resize(..., INTER_LINEAR)`` does it (pixel centres aligned, the border clamped), without the image: a
    candidate reads the share at one point, and upsampling the whole map for it cost more than the rest of the
    share's frame. Computed in float64, so it can differ from OpenCV's float32 result in the last bit."""
    h, w = coarse.shape

    def axis(d: int, n_out: int, n_in: int) -> tuple[int, int, float]:
        f = (d + 0.5) * n_in / n_out - 0.5
        s = math.floor(f)
        if s < 0:
            return 0, 0, 0.0
        if s >= n_in - 1:
            return n_in - 1, n_in - 1, 0.0
        return s, s + 1, f - s

    x0, x1, fx = axis(x, shape[1], w)
    y0, y1, fy = axis(y, shape[0], h)
    top = float(coarse[y0, x0]) * (1.0 - fx) + float(coarse[y0, x1]) * fx
    bottom = float(coarse[y1, x0]) * (1.0 - fx) + float(coarse[y1, x1]) * fx
    return top * (1.0 - fy) + bottom * fy


class ProjectorShare:
    """Per coarse tile, the projector's direct share of the membrane's light, learned from projected light.

    The working-size images a frame needs (the weight, ``z`` and one product at a time) are kept between frames and
    the per-tile sums live in one array per memory, so a frame costs a few passes over the image and a few dozen
    operations on tiles: it runs on every camera frame (the short memory), on a board with a core to spare for
    all of touch."""

    _sums: np.ndarray | None  # (5, rows, columns): weight, x, u, x^2, x*u per tile (x = light - 1, u = z - 1)
    _last_t: float | None
    _coarse: np.ndarray | None  # the share per tile, cached until the sums change
    _map: np.ndarray | None  # the same at the working size, made only when asked for (the probe's compensation)
    _expected: np.ndarray | None  # per tile: the reference's level, over its median, when last learned
    _fast: np.ndarray | None  # the same sums as _sums over FAST_TAU_S, on every frame
    _fast_t: float | None
    # Per memory, once the reference was re-seeded (:meth:`rebase`): (3, rows, columns) weight, variance and covariance
    # of the frames before, each about its own means, decayed as the sums are; None until then.
    _carry: np.ndarray | None
    _fast_carry: np.ndarray | None
    _k: float  # the last room factor solved: where Newton's method starts next
    updates: int

    def __init__(self, tau_s: float, tile_px: int = TILE_PX) -> None:
        """``tau_s``: time constant of the weighted sums (how long a share is remembered in steady light);
        ``tile_px``: a tile's side in the images' pixels (the same part of the membrane at any detection scale:
        :func:`feelium.touch.illumination.tile_px_for`)."""
        self.tau_s = tau_s
        self.tile_px = tile_px
        self._shape: tuple[int, int] | None = None
        self._images: dict[str, np.ndarray] = {}  # working-size scratch, reused frame after frame
        self.reset()

    def reset(self) -> None:
        """Forget what was learned (the working size stays until the next frame)."""
        self._sums = None
        self._last_t = None
        self._coarse = None
        self._map = None
        self._expected = None
        self._fast = None
        self._fast_t = None
        self._carry = None
        self._fast_carry = None
        self._k = 1.0
        self.updates = 0

    def _image(self, name: str, shape: tuple[int, int]) -> np.ndarray:
        """A float32 working-size scratch image (its contents are whatever the last frame left)."""
        image = self._images.get(name)
        if image is None or image.shape != shape:
            image = self._images[name] = np.empty(shape, np.float32)
        return image

    def learn(
        self, t: float, frame: np.ndarray, expected: np.ndarray, light: np.ndarray, usable: np.ndarray,
        *, hand_free: bool = True,
    ) -> None:
        """Add one frame (``hand_free``: False on a frame with a hand in view, which only the short memory of the
        membrane's level learns from, away from the shadows ``usable`` excludes): ``frame`` (working size, raw: the projected light not compensated), ``expected`` what the
        reference expects for the flat membrane (exposure gain times reference), ``light`` the predicted projector
        light relative to flat grey, ``usable`` the pixels free of shadows, saturation and darkness."""
        self._shape = frame.shape
        grid = tile_grid(frame.shape, self.tile_px)
        rows = slice(None, None, LEARN_ROW_STEP)
        frame, expected, light = (np.asarray(a, np.float32)[rows] for a in (frame, expected, light))
        usable = usable[rows]
        shape = frame.shape
        area = cv2.INTER_AREA
        weight = self._image("weight", shape)
        np.copyto(weight, usable)  # 1 where usable, 0 elsewhere
        # Per tile (INTER_AREA: means over its pixels): z, light and expected times the weight (0, 1, 2), the weight (3).
        tiles = np.empty((4, grid[1], grid[0]), np.float32)
        cv2.resize(weight, grid, dst=tiles[3], interpolation=area)
        z = cv2.max(expected, 1e-3, dst=self._image("z", shape))  # z is finite: expected is floored
        cv2.divide(frame, z, dst=z)
        cv2.multiply(z, weight, dst=z)  # frame / expected where usable, 0 elsewhere
        cv2.resize(z, grid, dst=tiles[0], interpolation=area)
        product = cv2.multiply(light, weight, dst=self._image("product", shape))
        cv2.resize(product, grid, dst=tiles[1], interpolation=area)
        cv2.multiply(expected, weight, dst=product)
        cv2.resize(product, grid, dst=tiles[2], interpolation=area)
        share = tiles[3]
        means = tiles[:3] / np.maximum(share, np.float32(1e-6))  # mz, mx, me: only tiles with half their pixels count
        me = means[2]
        finite = np.logical_and.reduce(np.isfinite(means), axis=0)  # all(axis=0) without its Python layer
        good = (share >= MIN_TILE_WEIGHT) & finite & (me > 0.0)
        # fresh: w, x * w, u * w, x^2 * w, x * u * w with w = good (0 or 1) and x, u 0 where it is 0: w multiplies
        # nothing away, so the products are the plain ones.
        fresh = np.zeros((5, grid[1], grid[0]))
        fresh[0] = good
        np.copyto(fresh[1:3], means[1::-1] - np.float32(1.0), where=good)  # x = mx - 1, u = mz - 1 (float32, widened)
        np.multiply(fresh[1], fresh[1:3], out=fresh[3:5])
        level = np.where(good, me / max(median(me[good]), 1e-6) if good.any() else 1.0, np.nan)
        self._follow(level)  # both memories, to today's reference, before today's frame joins them
        if self._expected is None or self._expected.shape != level.shape:
            self._expected = level
        else:
            np.copyto(self._expected, level, where=good)
        fast_dt = 0.0 if self._fast_t is None else max(t - self._fast_t, 0.0)
        self._fast_t = t
        if self._fast is None or self._fast.shape != fresh.shape:
            self._fast, self._fast_carry = fresh.copy(), None
        else:
            keep = math.exp(-fast_dt / FAST_TAU_S)
            self._fast *= keep
            self._fast += fresh
            if self._fast_carry is not None:
                self._fast_carry *= keep
        self._changed()
        if not hand_free:
            return
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        self._last_t = t
        if self._sums is None or self._sums.shape != fresh.shape:
            self._sums, self._carry = fresh, None
        else:
            keep = math.exp(-dt / self.tau_s)
            self._sums *= keep
            self._sums += fresh
            if self._carry is not None:
                self._carry *= keep
        self.updates += 1

    def _changed(self) -> None:
        """The sums moved: the maps made from them are stale."""
        self._coarse = None
        self._map = None

    def _follow(self, level: np.ndarray) -> None:
        """The room's slow change since the tiles last learned: where a tile's normalised reference went from ``then``
        to ``level`` the projector's share went from ``p`` to ``p * then / level``."""
        if self._expected is None or self._expected.shape != level.shape:
            return
        ratio = self._expected / level
        unknown = np.isfinite(ratio)
        np.logical_not(unknown, out=unknown)
        ratio.clip(0.25, 4.0, out=ratio)  # np.clip's arithmetic, in place and without its dispatch
        np.copyto(ratio, ratio.dtype.type(1.0), where=unknown)
        for sums, carry in ((self._sums, self._carry), (self._fast, self._fast_carry)):  # the short memory too: it
            if sums is not None and sums.shape[1:] == ratio.shape:  # judges the level against today's reference
                sums[2::2] *= ratio  # u and x*u
                if carry is not None:
                    carry[2] *= ratio  # the covariance with u

    def rescale(self, factor: np.ndarray) -> None:
        """The room's light changed: every tile's projector share is now ``factor`` (working size) times what it
        was (``e * reference / (e * reference + added)``, see the module docstring). The reference is re-seeded with
        it: :meth:`rebase`."""
        if self._sums is None:
            self.rebase()  # nothing to rescale yet, but the short memory's frames are divided by another reference
            return
        f = cv2.resize(factor.astype(np.float32), (self._sums.shape[2], self._sums.shape[1]), interpolation=cv2.INTER_AREA)
        f = np.clip(np.nan_to_num(f, nan=1.0, posinf=1.0, neginf=1.0), 0.0, 4.0).astype(np.float64)
        self._sums[2::2] *= f  # u = p * x: scaling p scales u (and its intercept, a gain error), and x*u with it
        if self._fast is not None:
            self._fast[2::2] *= f
        for carry in (self._carry, self._fast_carry):
            if carry is not None:
                carry[2] *= f
        self._expected = None  # the re-seeded reference is the new "then": its step is in ``factor`` already
        self.rebase()

    def rebase(self) -> None:
        """The reference was re-seeded or restarted: every tile's ``u`` may have stepped by a constant from this frame on.

        A re-seed copies one frame, as compensated, into the reference; whatever part of the projected pattern the
        compensation left in it (on a recording the photometric response's share, learned over 20 s, lags a passing
        person's shadow: a third of the probe stayed in the reference) divides every later frame: a new intercept per
        tile, of the probe's sign in every cell. Sums that mix frames before and after read that step, times the probe
        after it, as slope, the same way in every tile: after a passer's re-seed the short memory's pooled share read
        0.19-0.22 on a recording against the lab's 0.25-0.27, and the room factor ``k`` 1.16-1.33 while the room had
        darkened (a recorded tap held back as a hover). So each memory keeps what it learned as its variance and covariance about its own means so far
        (decayed with it) and starts its means anew: the intercept may differ on either side, the slope is the same."""
        if self._sums is not None:
            self._carry = np.stack(_centred(self._sums, self._carry))
            self._sums.fill(0.0)
        if self._fast is not None:
            self._fast_carry = np.stack(_centred(self._fast, self._fast_carry))
            self._fast.fill(0.0)
        self._changed()

    def room_scale(self, fitted: tuple[np.ndarray, np.ndarray] | None = None) -> float:
        """``k``: how much the room's light moved lately, everywhere alike, judged by the short fit (1.0 while either
        fit knows too little). Solved by Newton's method: the long fit's shares moved by ``k``, pooled with the
        short fit's weights (its change of light per tile), equal the short fit's pooled share. ``fitted``:
        :meth:`tiles`, when the caller has it.

        Newton starts from the last frame's ``k`` (the room moves little in a frame: one or two steps instead of four
        to eight from "unchanged"), and again from 1 when that fails to converge."""
        fitted = self.tiles() if fitted is None else fitted
        if fitted is None or self._fast is None or self._fast.shape[1:] != fitted[0].shape:
            return 1.0
        p, info = fitted
        n, var, cov = _centred(self._fast, self._fast_carry)  # the short memory's change of light, per tile
        known = (info > 0.0) & (var >= MIN_LIGHT_VAR * np.maximum(n, 1e-9))
        if not known.any():
            return 1.0
        pk, vk = p[known].astype(np.float64), var[known]
        target = float(np.sum(cov[known]))
        k, converged = _solve_room_scale(pk, vk, target, self._k)
        if not converged and self._k != 1.0:
            k, _ = _solve_room_scale(pk, vk, target, 1.0)
        self._k = k
        return k

    def tiles(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Per tile: the fitted share and how much change of light it saw (its weighted variance of ``light - 1``
        times its weight: the fit's information); None before anything was learned."""
        if self._sums is None:
            return None
        n, var, cov = _centred(self._sums, self._carry)  # weighted sums: per unit of weight they are the means'
        p = np.where(var > 0.0, cov / np.maximum(var, 1e-12), 0.0)
        info = np.where(var >= MIN_LIGHT_VAR * np.maximum(n, 1e-9), var, 0.0)
        return p.clip(*SHARE_LIMITS, out=p).astype(np.float32), info.astype(np.float32)  # np.clip less its dispatch

    def coarse(self) -> np.ndarray | None:
        """The projector's share per tile (float32), or None until some tile saw its light change.

        Every tile takes the share of the informative tiles around it (itself included), weighted by what they saw:
        a tile that straddles two of the probe's cells saw little change of light and its own fit is noisy (kept
        alone, such tiles put the share 0.1-0.2 off in places, and one lost a tap), at the price of a bias where the
        back-light's fall-off makes the share vary fast from tile to tile. Health judges the membrane at this
        resolution (a few hundred values a frame), and a candidate reads it at its point (:meth:`share_at`)."""
        if self._coarse is not None:
            return self._coarse
        fitted = self.tiles()
        if fitted is None:
            return None
        p, info = fitted
        most = float(info.max()) if info.size else 0.0  # info is >= 0 and never NaN: "any tile > 0" is its max > 0
        if not most > 0.0:
            return None
        weighted = p * info  # blurred and summed: made once
        num = cv2.GaussianBlur(weighted, (0, 0), SPREAD_SIGMA_TILES, borderType=cv2.BORDER_REPLICATE)
        den = cv2.GaussianBlur(info, (0, 0), SPREAD_SIGMA_TILES, borderType=cv2.BORDER_REPLICATE)
        total = np.add.reduce  # np.sum's own arithmetic, without its dispatch
        fallback = float(total(weighted, axis=None) / total(info, axis=None))
        # float32 throughout (the scalars are weak or float32): astype only names the type, it copies nothing.
        spread = np.where(den > 1e-3 * most, num / np.maximum(den, 1e-12), fallback).astype(np.float32, copy=False)
        k = np.float32(self.room_scale(fitted))
        spread = (spread / np.maximum(spread + k * (1.0 - spread), np.float32(1e-6))).clip(*SHARE_LIMITS)
        spread = spread.astype(np.float32, copy=False)
        self._coarse = spread
        return spread

    def share_map(self) -> np.ndarray | None:
        """The projector's share at every working pixel (float32; :meth:`coarse` upsampled), or None until some tile
        saw its light change. Made only when asked for: the probe's compensation needs every pixel."""
        if self._map is not None:
            return self._map
        spread = self.coarse()
        if spread is None or self._shape is None:
            return None
        h, w = self._shape
        self._map = cv2.resize(spread, (w, h), interpolation=cv2.INTER_LINEAR)
        return self._map

    def share_at(self, x: float, y: float) -> float | None:
        """The share at the working pixel nearest (``x``, ``y``) (clamped to the image), as :meth:`share_map` has it
        there but for the last bit (:func:`upsampled_at`), without making the map; None while it is unknown."""
        spread = self.coarse()
        if spread is None or self._shape is None:
            return None
        h, w = self._shape
        ix = min(max(int(round(x)), 0), w - 1)
        iy = min(max(int(round(y)), 0), h - 1)
        return upsampled_at(spread, self._shape, ix, iy)


def _centred(sums: np.ndarray, carry: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per tile, from a memory's sums (and its ``carry`` from before the last :meth:`ProjectorShare.rebase`): the weight,
    and the weighted sums of squares of ``x`` and of products ``x * u`` about their means (each side of a re-base about
    its own)."""
    n, sx, su, sxx, sxu = sums
    safe = np.maximum(n, 1e-9)
    var = np.maximum(sxx - sx * sx / safe, 0.0)
    cov = sxu - sx * su / safe
    if carry is None:
        return n, var, cov
    return n + carry[0], var + carry[1], cov + carry[2]


def _solve_room_scale(pk: np.ndarray, vk: np.ndarray, target: float, start: float) -> tuple[float, bool]:
    """Newton's method for ``k`` in ``sum(vk * pk / (pk + k (1 - pk))) = target`` from ``start`` (the pooled share
    falls smoothly as ``k`` grows), at most :data:`NEWTON_STEPS` steps: ``k`` and whether it converged (a step
    under 1e-4, or a limit of :data:`ROOM_SCALE_LIMITS` with the root beyond it, where it stays).

    The products that do not depend on ``k`` are made once (the same arithmetic, in the same order, as writing
    them inside the loop)."""
    qk = 1.0 - pk
    a = vk * pk
    aq = a * qk
    low, high = ROOM_SCALE_LIMITS
    total = np.add.reduce  # np.sum's own arithmetic, without its dispatch
    k = start
    for _ in range(NEWTON_STEPS):
        den = k * qk + pk  # >= min(1, k) >= 0.1: pk is clipped to 0..1 and k to its limits
        f = float(total(a / den)) - target
        den *= den
        slope = -float(total(aq / den))
        if slope >= -1e-12:
            return k, True
        step = f / slope
        if (k <= low and step > 0.0) or (k >= high and step < 0.0):
            return k, True  # at a limit, pushed beyond it
        k = min(max(k - step, low), high)
        if abs(step) < 1e-4:
            return k, True
    return k, False


def projected_depth(depth: float, share: float) -> float:
    """The share of the projector's own light a shadow of relative ``depth`` took away where the projector gives
    ``share`` of the flat membrane's light: ``1 - (1 - depth) / share``.

    All the light that is not the projector's (``1 - share``) can be blocked by a hand above the membrane; only
    what a shadow takes beyond it is projector light, which only skin on the membrane takes. At most 0 for a hand
    above it; for a contact the frustrated reflection's share. -inf where the projector gives nothing."""
    if share <= 0.0:
        return float("-inf")
    return 1.0 - (1.0 - depth) / share


# How far the learned share is off per place: the median absolute error against the simulator's truth over the
# lit room's trials (docs/touch.md, "The projector's share, per place"), rounded up.
SHARE_ERROR = 0.02


# The projector's share of the membrane's light (learned, per place or pooled) at the brightest room measured to work:
# room light 8x the projector's, every touch found and no hover fired (docs/touch.md, "How bright a room health
# vouches for", session 19: seed 31, 13 trials at each of 1, 2, 3, 5 and 8x). The pooled share's own floor is 0.05
# (photometric.SHARE_LIMITS): at it, the share no longer says how bright the room is.
MEASURED_SHARE_FLOOR = 0.055


def room_dominated(share: np.ndarray, considered: np.ndarray, floor: float = MEASURED_SHARE_FLOOR) -> float:
    """The fraction of the ``considered`` places where the room outshines the projector beyond anything measured.

    Why measured and not modelled: a model of the share's error and the depth's noise (the rule before session 19)
    put the lit living room's every frame beyond the gate, where the detector found every touch and fired no hover
    up to 8x the projector's light; what is known is that it works down to ``floor``, not below. 0 when nothing is
    considered."""
    total = int(np.count_nonzero(considered))
    if total == 0:
        return 0.0
    return float(np.count_nonzero((share < np.float32(floor)) & considered)) / total
