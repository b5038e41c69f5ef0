"""The touch pipeline: one camera frame in, touch decisions and events out.

Pure and frame-by-frame: time comes in with every frame, nothing reads a clock
or does I/O, so the daemon, `feelium replay`, `feelium eval` and the tests run
exactly the same code. Stages (each its own module):
geometry (ROI at working resolution; with a face model, only the face inside it,
:mod:`feelium.skin.face`) -> reference (exposure gain, adaptive
reference) -> depth (relative shadow depth, masked) -> candidates (components
of smoothed depth split into contacts, fingertip as core centroid, footprint
shape) -> gates + tracker (events).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from feelium.events import TouchEvent
from feelium.touch.buffers import Scratch
from feelium.touch.candidates import Candidate, Segmentation, find_candidates, shadow_boxes
from feelium.touch.config import TouchConfig
from feelium.touch.depth import MaskCounts, depth_against
from feelium.touch.geometry import LightGrids, WorkingGeometry
from feelium.touch.illumination import TILE_PX, illumination_change, reseed, tile_px_for
from feelium.touch.photometric import LIGHT_MAX, ProjectorResponse
from feelium.touch.reference import REFERENCE_FLOOR, AdaptiveReference
from feelium.touch.refine import (
    FineDetail,
    FineInputs,
    Window,
    fine_depth,
    fine_flat,
    fine_window,
    shifted,
    upsample_window,
)
from feelium.touch.roomshare import SHARE_ERROR, ProjectorShare, projected_depth, room_dominated
from feelium.touch.settle import depth_uncertainty, spread_window
from feelium.touch.shape import axes_from_moments, contact_shape
from feelium.touch.tracker import Contact, Observation, Tracker
from feelium.skin.coords import inside_roi, skin_uv
from feelium.skin.face import FaceModel

BACKLIGHT_MIN = 0.05  # predicted back-light scale below which a pixel carries no signal


@dataclass(frozen=True)
class FrameResult:
    """What one frame produced."""

    t: float
    events: tuple[TouchEvent, ...]  # emitted this frame (x, y in camera pixels of the input frame)
    activity: bool  # any shadow above the noise floor in the ROI (touch or not)
    anchor: float  # this frame's sustained-anchoring score (max over candidate shadows; 0.0 when none)
    depth_max: float  # largest (smoothed) relative shadow depth in the ROI this frame
    area: int  # darkened area (camera px) above the activity floor
    contacts: tuple[Contact, ...]  # contacts currently down
    core_depth: float = 0.0  # deepest candidate core this frame (what the instant gate sees)
    edge: float = 0.0  # that candidate's contact edge (steepest depth gradient, per camera px)
    # The largest share of the projector's own light any candidate took away (:mod:`feelium.touch.roomshare`);
    # None while the projector's share of the light is unknown.
    projected_depth: float | None = None


class TouchPipeline:
    """Rear-camera frames to touch events, restricted to the ROI, driven by frame timestamps."""

    def __init__(
        self,
        config: TouchConfig,
        frame_size: tuple[int, int],
        roi: tuple[int, int, int, int] | None,
        *,
        plain: bool = False,
        face: FaceModel | None = None,
    ) -> None:
        """frame_size = (width, height) of the camera frames fed in; roi = [x, y, w, h] in those pixels.

        ``face``: the whole front face (:class:`feelium.skin.face.FaceModel`, for this frame size). The sensitive
        area is then the face, not the rectangle: pixels off the face carry no depth and teach the reference
        nothing, a shadow centred off it is dropped, and u, v are the face's (azimuth, elevation on the envelope).
        The ROI stays the box the working image is cut from (the face's bounding box when ``roi`` is None).
        Without it the pipeline is the paper's rectangle, unchanged.

        ``plain=True`` runs the same algorithm the plain way (float64, whole
        frame at camera resolution, candidates outside the ROI dropped); it is
        the speed and accuracy baseline of `feelium bench touch`.
        """
        self.config = config
        if face is not None:
            if (face.width, face.height) != tuple(frame_size):
                raise ValueError(f"face model is for {face.width}x{face.height} frames, camera is {frame_size}")
            roi = face.roi() if roi is None else roi
        self.face = face
        self.plain = plain
        self.fine: WorkingGeometry | None = None  # the working resolution, when detection runs coarser
        if plain:
            self.geometry = WorkingGeometry.build(frame_size, None, frame_size, np.float64)
            self._roi = WorkingGeometry.build(frame_size, roi, frame_size, np.float64).roi
        else:
            # With detect_scale < 1 the per-pixel work runs at that fraction of the working resolution and the
            # candidates are found again at the working resolution around the shadows (feelium.touch.refine).
            scale = config.detect_scale
            self.geometry = WorkingGeometry.build(
                frame_size, roi, (config.width * scale, config.height * scale), np.float32
            )
            self._roi = self.geometry.roi
            if scale < 1.0:
                self.fine = WorkingGeometry.build(frame_size, roi, (config.width, config.height), np.float32)
        # The room-light and share tiles' side in detection pixels: a fixed part of the membrane at any scale.
        self._tile_px = TILE_PX if self.fine is None else tile_px_for(config.detect_scale)
        self._off_face = None if face is None else self._cut_off_face(face, self.geometry)
        self._fine_off_face = None if face is None or self.fine is None else self._cut_off_face(face, self.fine)
        self.reference = AdaptiveReference(
            tau_s=config.reference_tau_s,
            bright_tau_s=config.reference_bright_tau_s,
            forced_tau_s=config.reference_forced_tau_s,
            dark_level=config.dark_reference_level,
            saturation_level=float(config.saturation_level),
            rebaseline_step=config.rebaseline_gain_step,
            sample_step=config.gain_sample_step,
            bright_margin=config.noise_floor,
            row_clip=config.row_gain_clip,
        )
        self.tracker = Tracker(config)
        self.response = ProjectorResponse(tau_s=config.projected_response_tau_s, prior_var=config.projected_prior_var)
        self.projector_share = ProjectorShare(tau_s=config.projector_share_tau_s, tile_px=self._tile_px)
        self.settled = True  # False while the projected light's response is not learned: nothing new is raised
        self.uncertain_frames = 0  # frames in which the prediction's spread could fake a darkened pixel
        self._reference_share = self.response.share
        self.masked = MaskCounts()
        self.frames = 0
        self.light_changes = 0  # frames on which a membrane-wide change of light re-seeded the reference
        # Share of the membrane where the room outshines the projector beyond anything measured to work
        # (:func:`feelium.touch.roomshare.room_dominated`); None while the projector's share is not known.
        self.room_dominated: float | None = None
        self._room_judged_t: float | None = None  # when room_dominated was last judged
        self._learned_t: float | None = None  # when the response last learned (RESPONSE_LEARN_INTERVAL_S)
        self.noise = 0.0
        self._last_t: float | None = None
        self._shadow: np.ndarray | None = None
        self._deep: np.ndarray | None = None
        # Working-size temporaries reused every frame (feelium.touch.buffers): none outlives its frame.
        self._scratch = Scratch()
        g = self.geometry
        self._sigma = g.px(config.blur_sigma_px)
        self._edge_radius = g.px(config.contact_edge_radius_px)
        self._min_area = max(1, int(math.ceil(config.candidate_min_area_px / g.area_scale)))
        self._activity_area = config.activity_min_area_px
        self._fine_scratch = Scratch()
        self.detail = FineDetail(tau_s=config.reference_tau_s, interval_s=DETAIL_INTERVAL_S)
        if self.fine is not None:
            f = self.fine
            self._fine_sigma = f.px(config.blur_sigma_px)
            self._fine_edge_radius = f.px(config.contact_edge_radius_px)
            self._fine_min_area = max(1, int(math.ceil(config.candidate_min_area_px / f.area_scale)))
            # The window reaches past the coarse shadows by the blur's support and the edge's radius.
            self._fine_margin = int(math.ceil(3.0 * self._fine_sigma + self._fine_edge_radius)) + 2
        margin = int(math.ceil(g.px(config.reference_margin_px)))
        self._margin_kernel = (
            cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin + 1, 2 * margin + 1)) if margin > 0 else None
        )

    @property
    def roi(self) -> tuple[int, int, int, int]:
        return self._roi

    @property
    def light_grids(self) -> LightGrids | None:
        """Where to predict the projected light when detection runs coarser (``detect_scale`` < 1): the detection
        grid and the working resolution's, each a (frame size, box) whose box pixels are the working images' own
        (:meth:`WorkingGeometry.light_grid`); the fine one may be None (the fine pass then upsamples the coarse
        light). None at scale 1, or when the coarse grid is not whole pixels or not a whole fraction of the working
        one: the light is then passed at the camera's size or the ROI's, as always. Why: predicting at the
        detection size costs a quarter of the pixels at 0.5, and averaging a full-size prediction down cost the
        prediction, the mix and the area resize in full."""
        if self.fine is None:
            return None
        coarse = self.geometry.light_grid()
        (cw, ch), (fw, fh) = self.geometry.work_size, self.fine.work_size
        ratio = fw // cw
        if coarse is None or (fw, fh) != (ratio * cw, ratio * ch):
            return None
        return LightGrids(coarse, self.fine.light_grid(), ratio)

    def reset(self) -> None:
        """Forget the reference, tracks and time (a new recording or a camera restart)."""
        self.reference.reset()
        self.tracker.reset()
        self.response.reset()
        self.detail.reset()
        self.projector_share.reset()
        self.room_dominated = None
        self._room_judged_t = None
        self._learned_t = None
        self.settled = True
        self._reference_share = self.response.share
        self._last_t = None
        self._shadow = None
        self._deep = None

    def finish(self) -> tuple[TouchEvent, ...]:
        """Release contacts still down at the last frame's time (end of a recording)."""
        if self._last_t is None:
            return ()
        return tuple(self.tracker.finish(self._last_t))

    def process(
        self,
        t: float,
        frame: np.ndarray,
        backlight_gain: np.ndarray | None = None,
        *,
        projected_light: np.ndarray | None = None,
        projected_spread: np.ndarray | None = None,
        probe_light: np.ndarray | None = None,
        fine_light: Callable[[slice, slice], np.ndarray | None] | None = None,
    ) -> FrameResult:
        """One camera frame (gray uint8 (H, W) or BGR (H, W, 3)) at camera time ``t`` (strictly increasing).

        ``projected_light`` (camera frame size, or already cut to the ROI's size, float): the projector light
        predicted for the exposure of this frame, relative to the flat grey (1.0); it is compensated through the per-pixel response learned online
        (:mod:`feelium.touch.photometric`). ``projected_spread`` (same size): how far that prediction may be off
        per pixel (:func:`feelium.touch.settle.predicted_exposure`); every shadow is taken at the smallest depth
        the spread allows and uncertain pixels learn nothing (:mod:`feelium.touch.settle`). ``backlight_gain`` is
        the older multiplicative model (divide it out).

        ``probe_light`` (same sizes as ``projected_light``): on a skin whose content is not passed as
        ``projected_light``, the light of the projector's faint probe pattern relative to flat grey; it teaches the
        projector's share of the light per place (:mod:`feelium.touch.roomshare`) and is compensated with it.
        Wherever that share is known (from the probe or from ``projected_light``), a candidate that takes less than
        ``contact_projected_depth`` of the projector's own light away is a hand above the membrane, not a contact.

        With ``detect_scale`` < 1, ``projected_light`` and ``projected_spread`` may also come at the detection size
        (predicted on :attr:`light_grids`' coarse grid), and ``fine_light(rows, cols)`` gives the same exposure's
        light at the working resolution over a window of the fine image (predicted there only; the pipeline may
        write into the array it returns; when it returns None or is not given, the fine pass upsamples the coarse
        light).
        """
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f"frame time {t} is not finite")
        if self._last_t is not None and t <= self._last_t:
            raise ValueError(f"frame time {t} does not follow the previous frame time {self._last_t}")
        work, unusable = self._prepare(frame, backlight_gain)
        if self._off_face is not None:
            unusable = self._off_face if unusable is None else (unusable | self._off_face)
        light = None if projected_light is None else self._cut_light(projected_light, "light")
        spread = None
        if light is not None and projected_spread is not None:
            spread = self._cut_light(projected_spread, "spread", unknown=LIGHT_MAX)
        probe = None if probe_light is None else self._cut_light(probe_light, "probe")
        raw = work
        if light is not None:
            # Until the response is learned nothing is settled: the compensation is only a guess.
            self.settled = self.response.share is not None
            work = self.response.compensate(raw, light)
            np.copyto(work, np.float32(self.config.saturation_level), where=raw >= self.config.saturation_level)
        elif probe is not None:
            work = self._compensate_probe(raw, probe)
        self._last_t = t
        self.frames += 1
        ref = self.reference
        if ref.image is None:
            ref.initialise(t, work)
            self._shadow = np.zeros(work.shape, bool) if self._off_face is None else self._off_face.copy()
            self._deep = None
            return FrameResult(t, (), False, 0.0, 0.0, 0, (), 0.0)
        cfg = self.config
        usable = self._usable(work) if self.settled else None  # the gain's and the light's pixels, made once
        gain = ref.measure_gain(work, self._shadow, usable)
        stepped = abs(gain / ref.gain - 1.0) > cfg.rebaseline_gain_step
        if usable is not None and self._follow_light(work, stepped, usable):
            gain = ref.measure_gain(work, self._shadow)
            self.response.request_fit()  # the room's light changed: the projector's share of it may have too
        if self.settled:
            ref.observe_gain(gain, work, self._shadow)
        ref.measure_rows(work, self._deep)
        buf = self._scratch
        # What the flat membrane gives this frame (the reference times its gain), made once: the depth, the spread's
        # bound, the fine pass and the share's lesson read it; the reference does not change before its update.
        expected = np.multiply(ref.image, ref.expected_gain(), out=buf.like("expected", ref.image))
        depth = depth_against(
            work,
            expected,
            dark_level=cfg.dark_reference_level,
            saturation_level=float(cfg.saturation_level),
            counts=self.masked,
            signed=True,
            scratch=buf,
        )
        if self._off_face is not None:
            depth[self._off_face] = 0.0  # the black envelope: no back-light, no signal
        if self._sigma > 0.2:
            smooth = cv2.GaussianBlur(
                depth, (0, 0), self._sigma, dst=buf.like("smooth", depth), borderType=cv2.BORDER_REPLICATE
            )
        else:
            smooth = depth
        floor = _noise_floor_map(smooth, cfg.noise_sigmas, cfg.noise_floor, buf)
        self.noise = float(floor.max()) if floor.size else 0.0
        uncertain = None
        bound_full = None
        # The bound is zero where the spread is (inside a scene: most frames, most pixels), so it is computed only
        # in the window around the nonzero spread (:func:`feelium.touch.settle.spread_window`); bit for bit the same.
        window = None if spread is None or self.response.slope is None else spread_window(spread, self._sigma, buf)
        if window is not None:
            lit = buf.like("uncertainty.expected", ref.image)
            np.maximum(expected[window], np.float32(cfg.dark_reference_level), out=lit[window])
            bound = depth_uncertainty(spread, self.response.slope, lit, self._sigma, buf, window)
            smooth[window] -= bound  # the smallest depth the prediction allows: its error cannot make a shadow
            if self.fine is not None:
                bound_full = np.zeros(smooth.shape, smooth.dtype)
                bound_full[window] = bound
            uncertain = np.zeros(smooth.shape, bool)
            np.greater_equal(bound, cfg.noise_floor, out=uncertain[window])
            self.uncertain_frames += bool(uncertain[window].any())
        np.maximum(smooth, 0.0, out=smooth)
        shadow = np.greater(smooth, floor, out=buf.like("shadow.raw", smooth, bool))
        # Opening drops isolated specks of noise and keeps the area of real shadows.
        shadow = cv2.morphologyEx(shadow.view(np.uint8), cv2.MORPH_OPEN, _SPECK_KERNEL).view(bool)
        darkened = int(np.count_nonzero(shadow))
        area = int(round(darkened * self.geometry.area_scale))
        depth_max = float(smooth.max()) if smooth.size else 0.0
        boxes: list[tuple[int, int, int, int]] = []
        if self.fine is None:
            candidates, _ = self._find(
                smooth, self._min_area, self._edge_radius, buf, room_floor=self._room_floor(lambda x, y: (x, y))
            )
        else:  # the coarse pass only says where to look (fine_window): the boxes of the shadows candidates come from
            candidates = []
            boxes = shadow_boxes(
                smooth, threshold=cfg.candidate_depth, min_area=self._min_area, max_candidates=cfg.max_candidates,
                scratch=buf,
            )  # fmt: skip
        geometry = self.geometry
        fine_inputs = None
        learn_detail = self.fine is not None and self.settled and self.detail.due(t)
        if self.fine is not None and (boxes or learn_detail):
            lights = None if light is None else (projected_light, light, fine_light)
            fine_inputs = self._fine_inputs(frame, backlight_gain, lights, bound_full, expected)
        if boxes and fine_inputs is not None:
            # The fine depth decides, as the full-resolution path would: a coarse shadow it finds nothing in is none.
            candidates, geometry = self._refine(fine_inputs, boxes), self.fine
        observations = []
        kept = []
        # The share per tile is made when something reads it: a candidate, or health's judgement of the room.
        judge = self._room_judged_t is None or t - self._room_judged_t >= ROOM_JUDGE_INTERVAL_S
        coarse = None
        if cfg.contact_projected_depth > 0.0 and (candidates or judge):
            coarse = self.projector_share.coarse()
        if coarse is not None and judge:
            self._room_judged_t = t
            grid = (coarse.shape[1], coarse.shape[0])
            if unusable is None:
                considered = np.ones(coarse.shape, bool)
            else:
                considered = cv2.resize((~unusable).astype(np.float32), grid, interpolation=cv2.INTER_AREA) >= 0.5
            self.room_dominated = room_dominated(coarse, considered)
        most_projected: float | None = None
        for cand in candidates:
            cx, cy = geometry.to_camera(cand.x, cand.y)
            # Where the candidate lies in the detection image (the coarse candidate's own point at scale 1).
            point = (cand.x, cand.y) if geometry is self.geometry else self.geometry.from_camera(cx, cy)
            projected = True  # took the projector's own light away (unknown: assumed, as before the share)
            share = None
            gate_at = self._gate_point(cand, geometry, point)
            if coarse is not None:
                share = self.projector_share.share_at(*gate_at)
            if share is not None:
                taken = projected_depth(cand.peak, share) / _present_light(light, gate_at)
                most_projected = taken if most_projected is None else max(most_projected, taken)
                projected = taken >= cfg.contact_projected_depth  # else all its depth is light from outside
            if self.face is not None:
                fu, fv = self.face.to_uv(cx, cy)
                u, v = float(fu), float(fv)
                if not (0.0 <= u < 1.0 and 0.0 <= v < 1.0):  # NaN fails too
                    continue
            elif self.plain and not inside_roi(self._roi, cx, cy):
                continue
            else:
                u, v = skin_uv(self._roi, cx, cy)
            area_px = int(round(cand.area * geometry.area_scale))
            edge = cand.edge * geometry.px(1.0)  # a gradient per working px in per camera px
            cov = geometry.cov_to_camera(cand.footprint_cov)
            shape = contact_shape(cfg, cand.footprint_area * geometry.area_scale, cov)
            reach = 0.5 * axes_from_moments(*cov)[0]
            observations.append(Observation(cx, cy, u, v, cand.core_depth, area_px, edge, shape, reach, projected))
            kept.append(point)
        step = self.tracker.step(t, observations, settled=self.settled)
        if self._margin_kernel is not None and darkened:
            shadow = _dilated(shadow, self._margin_kernel)
        seeds = [point for point, p in zip(kept, step.protected) if p]
        anchored = _regions_containing(shadow, seeds) if seeds else None
        frozen = shadow if unusable is None else (shadow | unusable)
        if uncertain is not None:
            frozen = frozen | uncertain
        if learn_detail and fine_inputs is not None:
            self._learn_detail(t, fine_inputs, frozen)
        sensed = light if light is not None else probe
        learn_share = sensed is not None and self.settled
        learn_response = light is not None and (
            self._learned_t is None or t - self._learned_t >= 0.75 * RESPONSE_LEARN_INTERVAL_S
        )
        if learn_response:
            self._learned_t = t
        free = None  # neither frozen nor saturated: what the response and the share learn from (one mask for both)
        if learn_response or learn_share:
            free = np.logical_not(frozen, out=buf.like("learn.free", frozen))
            free &= np.less(raw, cfg.saturation_level, out=buf.like("learn.unsaturated", frozen))
        # Learned on hand-free frames only: a shadow's slow change under a tile, while the probe happens to rise or
        # fall, reads as light following the projector (a hover's own tiles came out 0.06 too projector-lit).
        # A frame with a hand teaches only the membrane's level of share, from the pixels away from its shadow.
        if learn_share:
            assert free is not None
            usable = np.greater_equal(expected, cfg.dark_reference_level, out=buf.like("share.usable", frozen))
            usable &= free
            hand_free = not candidates and area < self._activity_area
            self.projector_share.learn(t, raw, expected, sensed, usable, hand_free=hand_free)
        if self.settled:
            ref.update(t, work, frozen, anchored)
        else:
            ref.hold(t)
        if learn_response:
            assert free is not None
            moved = self.response.learn(t, raw, light, free)
            share, based = self.response.share, self._reference_share
            if share is not None and (based is None or _rebases(abs(share - based), light)):
                # The model of what the flat membrane looks like changed (first fit, a new room light):
                # the reference was built on the old one, so it starts again from the next frame. A share's
                # change moves the compensated frame by that change times ``1 - light`` (in the flat membrane's
                # units): under a face about the change itself, on a static skin, lit only by the probe's few
                # percent, a small part of it, which the reference follows without starting again (it started
                # again under a held hand when the probe's share wavered after a lamp went off: the hold was lost).
                ref.reset()
                self.projector_share.rebase()  # the frames it divides will be by another reference
                self._reference_share = share
            elif moved is not None and ref.image is not None:
                # Short of a new start, the reference moves with the compensation: each solve moves every later
                # frame by ``moved * (1 - light)``. On a static skin the light is the same frame after frame, so that
                # is exactly where the membrane now sits. A static skin's first solves, from a few frames of the
                # probe, moved the compensation of its dark places by up to a fifth of the light while the pooled
                # share moved less than the re-base's limit: left to the reference (4 s, frozen under what it read
                # as shadow), that was a shadow over a tenth of the membrane for seconds, no frame was hand-free,
                # and the share per place never learned (a press then read as a hover: session 17's known defect).
                change = np.subtract(np.float32(1.0), light, out=buf.like("carry.change", light, np.float32))
                change *= moved
                ref.carry(change)
        self._shadow = frozen
        self._deep = (smooth > cfg.candidate_depth) if candidates else None
        deepest = max(observations, key=lambda o: o.depth, default=None)
        return FrameResult(
            t=t,
            events=tuple(step.events),
            activity=area >= self._activity_area,
            anchor=step.anchor,
            depth_max=depth_max,
            area=area,
            contacts=tuple(self.tracker.contacts()),
            core_depth=deepest.depth if deepest else 0.0,
            edge=deepest.edge if deepest else 0.0,
            projected_depth=most_projected,
        )

    def _usable(self, work: np.ndarray) -> np.ndarray:
        """The pixels the exposure gain and the room's light are measured on: the reference times the current gain
        at least the dark level, the frame under saturation, off the last frame's shadow (this frame's buffer)."""
        ref, cfg, buf = self.reference, self.config, self._scratch
        assert ref.image is not None
        lit = np.multiply(ref.image, ref.gain, out=buf.like("follow.lit", ref.image))
        usable = np.greater_equal(lit, cfg.dark_reference_level, out=buf.like("follow.usable", work, bool))
        other = np.less(work, cfg.saturation_level, out=buf.like("follow.other", work, bool))
        usable &= other
        if self._shadow is not None:
            usable &= np.logical_not(self._shadow, out=other)
        return usable

    def _follow_light(self, work: np.ndarray, stepped: bool, usable: np.ndarray) -> bool:
        """Re-seed the reference on a membrane-wide change of light's shape (:mod:`feelium.touch.illumination`),
        or on any lighting step (``stepped``: the exposure gain jumped), so that under shadows the old reference
        is scaled by the change measured around them rather than by one gain. ``usable``: :meth:`_usable`."""
        ref, cfg, buf = self.reference, self.config, self._scratch
        assert ref.image is not None
        change = illumination_change(
            work, ref.image, ref.gain, usable, cfg.noise_floor, buf, force=stepped, tile_px=self._tile_px
        )
        if change is None:
            return False
        self.light_changes += 1
        e, added = change
        old = ref.image * np.float32(e)
        with np.errstate(invalid="ignore", divide="ignore"):
            self.projector_share.rescale(old / np.maximum(old + added, np.float32(REFERENCE_FLOOR)))
        image = reseed(ref.image, work * np.float32(1.0 / ref.gain), change, self._shadow)
        ref.image = np.maximum(image, image.dtype.type(REFERENCE_FLOOR))
        return True

    def _fine_inputs(
        self,
        frame: np.ndarray,
        backlight_gain: np.ndarray | None,
        lights: tuple[np.ndarray, np.ndarray, Callable[[slice, slice], np.ndarray | None] | None] | None,
        bound: np.ndarray | None,
        expected: np.ndarray,
    ) -> FineInputs:
        """This frame at the working resolution and the coarse pass's state it is read against
        (feelium.touch.refine); ``lights``: (projected light as passed, its cut, ``fine_light``), None when this
        frame is not compensated; ``expected``: the reference times its gain (detection size)."""
        fine = self.fine
        assert fine is not None and self.reference.image is not None
        work, _ = self._prepare(frame, backlight_gain, fine, "fine.work")
        slope = self.response.slope if lights is not None else None
        light = None if slope is None or lights is None else self._fine_light(*lights)
        return FineInputs(work, expected, light, slope, bound, self._fine_off_face, self.detail.ratio)

    def _fine_light(
        self,
        projected_light: np.ndarray,
        coarse_light: np.ndarray,
        fine_light: Callable[[slice, slice], np.ndarray | None] | None,
    ) -> Callable[[Window], np.ndarray]:
        """The projected light at the working resolution over a window of the fine image: predicted there
        (``fine_light``), else cut from a light passed at the camera's or the ROI's size, else (a light passed at
        the detection size only) ``coarse_light``, this frame's cut light, upsampled."""
        fine = self.fine
        assert fine is not None
        buf = self._fine_scratch

        def upsampled(window: Window) -> np.ndarray:
            rows, cols = window
            out = buf.get("fine.light_up", (rows.stop - rows.start, cols.stop - cols.start), fine.dtype)
            return upsample_window(coarse_light, fine.work_size, window, out)

        if fine_light is not None:

            def predicted(window: Window) -> np.ndarray:
                light = fine_light(*window)
                return upsampled(window) if light is None else _clean_light(light.astype(fine.dtype, copy=False), 0.0)

            return predicted
        if _light_is(projected_light, fine):
            whole = self._cut_light(projected_light, "fine.light", geometry=fine)
            return lambda window: whole[window]
        return upsampled

    def _refine(self, inputs: FineInputs, boxes: list[tuple[int, int, int, int]]) -> list[Candidate]:
        """The candidates found at the working resolution around the coarse pass's shadows (``boxes``, detection
        pixels), in fine working coordinates."""
        fine, cfg = self.fine, self.config
        assert fine is not None
        window = fine_window(boxes, self.geometry, fine, self._fine_margin)
        buf = self._fine_scratch
        smooth = fine_depth(
            inputs, window, sigma=self._fine_sigma, dark_level=cfg.dark_reference_level,
            saturation_level=float(cfg.saturation_level), scratch=buf,
        )  # fmt: skip
        dx, dy = window[1].start, window[0].start

        def to_detection(x: float, y: float) -> tuple[float, float]:
            return self.geometry.from_camera(*fine.to_camera(x + dx, y + dy))

        found, _ = self._find(
            smooth, self._fine_min_area, self._fine_edge_radius, buf, room_floor=self._room_floor(to_detection)
        )
        return [shifted(c, window) for c in found]

    def _gate_point(
        self, cand: Candidate, geometry: WorkingGeometry, point: tuple[float, float]
    ) -> tuple[float, float]:
        """Where the projected gate reads the share for ``cand`` (detection image): its whole core's centroid, which is
        ``point`` unless the fingertip was taken from the part below the room's floor (:func:`find_candidates`). The
        gate is judged where it was before that localisation, so it fires exactly as it did."""
        if cand.core_point is None:
            return point
        if geometry is self.geometry:
            return cand.core_point
        return self.geometry.from_camera(*geometry.to_camera(*cand.core_point))

    def _room_floor(
        self, to_detection: Callable[[float, float], tuple[float, float]]
    ) -> Callable[[float, float], float | None] | None:
        """The deepest a hand above the membrane can darken a point (given in the coordinates ``to_detection`` maps
        to the detection image): the light that is not the projector's, ``1 - share``, plus the share's error
        (:data:`SHARE_ERROR`); None at a point whose share is unknown, and no function while the share is not
        used (``contact_projected_depth`` 0). Read only for a candidate, so the share map is made only then."""
        if self.config.contact_projected_depth <= 0.0:
            return None
        share_at = self.projector_share.share_at

        def floor(x: float, y: float) -> float | None:
            share = share_at(*to_detection(x, y))
            return None if share is None else 1.0 - share + SHARE_ERROR

        return floor

    def _find(
        self,
        smooth: np.ndarray,
        min_area: int,
        edge_radius: float,
        scratch: Scratch,
        *,
        room_floor: Callable[[float, float], float | None] | None = None,
    ) -> tuple[list[Candidate], Segmentation | None]:
        """The candidates in a smoothed depth image with the config's gates, at one resolution's sizes
        (``room_floor``: :func:`find_candidates`'s)."""
        cfg = self.config
        return find_candidates(
            smooth,
            threshold=cfg.candidate_depth,
            min_area=min_area,
            core_fraction=cfg.core_fraction,
            max_candidates=cfg.max_candidates,
            edge_radius=edge_radius,
            scratch=scratch,
            split_fraction=cfg.contact_split_fraction,
            room_floor=room_floor,
        )

    def _learn_detail(self, t: float, inputs: FineInputs, frozen: np.ndarray) -> None:
        """Teach the fine pattern of the flat membrane from this frame where the coarse pass froze nothing."""
        cfg, buf = self.config, self._fine_scratch
        h, w = inputs.work.shape
        whole = (slice(0, h), slice(0, w))
        sat = float(cfg.saturation_level)
        flat = fine_flat(inputs, whole, saturation_level=sat, scratch=buf)
        expected = upsample_window(inputs.expected, (w, h), whole, buf.like("detail.expected", inputs.work))
        shadowed = cv2.resize(
            frozen.view(np.uint8), (w, h), dst=buf.like("detail.frozen", inputs.work, np.uint8),
            interpolation=cv2.INTER_NEAREST,
        )  # fmt: skip
        usable = np.less(inputs.work, sat, out=buf.like("detail.usable", inputs.work, bool))
        usable &= shadowed == 0
        usable &= expected >= cfg.dark_reference_level
        self.detail.learn(t, flat, expected, usable)

    def _compensate_probe(self, raw: np.ndarray, probe: np.ndarray) -> np.ndarray:
        """``raw + p * (1 - probe) * expected``: the frame as the flat grey would have lit it, with the projector's
        share ``p`` learned so far (the frame itself while it is unknown or before the reference exists)."""
        share, ref = self.projector_share.share_map(), self.reference
        if share is None or ref.image is None:
            return raw
        out = self._scratch.like("probe.compensated", raw)
        np.subtract(np.float32(1.0), probe, out=out)
        out *= share
        out *= ref.image
        out *= ref.expected_gain()
        out += raw
        np.copyto(out, np.float32(self.config.saturation_level), where=raw >= self.config.saturation_level)
        return out

    def _prepare(
        self,
        frame: np.ndarray,
        backlight_gain: np.ndarray | None,
        geometry: WorkingGeometry | None = None,
        name: str = "work",
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Validate the frame; return the gray working image (back-light divided out) and unusable pixels, at
        ``geometry``'s resolution (default the pipeline's), in the buffer ``name``."""
        g = self.geometry if geometry is None else geometry
        fw, fh = g.frame_size
        if not isinstance(frame, np.ndarray):
            raise ValueError(f"frame must be a numpy array, got {type(frame).__name__}")
        if frame.dtype != np.uint8:
            raise ValueError(f"frame must be uint8, got {frame.dtype}")
        if frame.shape[:2] != (fh, fw) or frame.ndim not in (2, 3) or (frame.ndim == 3 and frame.shape[2] not in (1, 3)):
            raise ValueError(f"frame shape {frame.shape} does not match the camera's {fw}x{fh} (gray or BGR)")
        x, y, w, h = g.roi
        part = frame[y : y + h, x : x + w]
        if part.ndim == 3:
            part = part[:, :, 0] if part.shape[2] == 1 else cv2.cvtColor(part, cv2.COLOR_BGR2GRAY)
        work = g.cut_roi(part, out=self._scratch.get(name, (g.work_size[1], g.work_size[0]), g.dtype))
        if backlight_gain is None:
            return work, None
        if backlight_gain.shape != (fh, fw):
            raise ValueError(f"backlight_gain shape {backlight_gain.shape} does not match the camera's {fw}x{fh}")
        light = np.nan_to_num(
            g.cut_roi(backlight_gain[y : y + h, x : x + w].astype(np.float32, copy=False)),
            nan=0.0,
            posinf=0.0,
            neginf=0.0,
        )
        unusable = light < BACKLIGHT_MIN
        np.maximum(light, BACKLIGHT_MIN, out=light)
        work /= light
        work[unusable] = float(self.config.saturation_level)
        return work, unusable

    @staticmethod
    def _cut_off_face(face: FaceModel, geometry: WorkingGeometry) -> np.ndarray:
        """Pixels of the ROI at ``geometry``'s resolution that lie mostly off the face (bool)."""
        x, y, w, h = geometry.roi
        on = face.mask()[y : y + h, x : x + w].astype(np.float32)
        return geometry.cut_roi(on) < 0.5

    def _cut_light(
        self, projected_light: np.ndarray, name: str, *, unknown: float = 0.0, geometry: WorkingGeometry | None = None
    ) -> np.ndarray:
        """The predicted light (or its spread) over the ROI at working resolution; NaN and inf become ``unknown`` (no
        light; for a spread, as uncertain as light can be), negatives 0, the rest is clipped to the range. Written
        into the buffer ``name`` (valid for this frame), at ``geometry``'s resolution (default the pipeline's)."""
        g = self.geometry if geometry is None else geometry
        fw, fh = g.frame_size
        x, y, w, h = g.roi
        out = self._scratch.get(name, (g.work_size[1], g.work_size[0]), g.dtype)
        if projected_light.shape == (fh, fw):
            projected_light = projected_light[y : y + h, x : x + w]
        elif projected_light.shape != (h, w):
            if projected_light.shape != out.shape:
                raise ValueError(
                    f"projected_light shape {projected_light.shape} is neither the camera's {fw}x{fh}, the ROI's "
                    f"{w}x{h} nor the working image's {g.work_size[0]}x{g.work_size[1]}"
                )
            if projected_light.dtype == out.dtype and cv2.checkRange(projected_light)[0]:
                # All finite (almost always): the copy and the clip are one pass, _clean_light's bits.
                return projected_light.clip(0.0, LIGHT_MAX, out=out)
            np.copyto(out, projected_light)  # predicted on the working grid (light_grids): nothing to resize
            return _clean_light(out, unknown)
        # Resized first (a NaN stays local to its neighbourhood), then cleaned on the small image: cheaper.
        return _clean_light(g.cut_roi(projected_light.astype(np.float32, copy=False), out=out), unknown)


def _clean_light(light: np.ndarray, unknown: float) -> np.ndarray:
    """``light`` in place: NaN and inf become ``unknown``, negatives 0, the rest clipped to the light's range."""
    if not cv2.checkRange(light)[0]:  # one pass, and almost always all finite: nan_to_num takes four
        np.nan_to_num(light, copy=False, nan=unknown, posinf=unknown, neginf=0.0)
    light.clip(0.0, LIGHT_MAX, out=light)  # the method: np.clip less its dispatch
    return light


def _light_is(light: np.ndarray, geometry: WorkingGeometry) -> bool:
    """Whether ``light`` is of the camera frame's size or the ROI's (what :meth:`TouchPipeline._cut_light` cuts)."""
    fw, fh = geometry.frame_size
    return light.shape in ((fh, fw), (geometry.roi[3], geometry.roi[2]))


SHARE_REBASE = 0.05  # change of the compensated flat membrane (its share's change times 1 - light) that re-bases
LIGHT_REACH_STEP = 4  # the light's reach is read on every 4th pixel both ways (a face's dark or bright parts are larger)


def _rebases(moved: float, light: np.ndarray) -> bool:
    """Whether a change of the learned share by ``moved`` moves the compensated membrane past :data:`SHARE_REBASE`.
    The light's reach is at most 1, so it is read only when the share itself moved that far (most frames it did
    not)."""
    return moved > SHARE_REBASE and moved * _light_reach(light) > SHARE_REBASE


def _light_reach(light: np.ndarray) -> float:
    """How far the predicted light strays from the flat grey, ``max |1 - light|`` (at most 1, the face's case)."""
    sample = light[::LIGHT_REACH_STEP, ::LIGHT_REACH_STEP]
    with np.errstate(invalid="ignore"):
        reach = float(np.nanmax(np.abs(np.float32(1.0) - sample))) if sample.size else 1.0
    return min(1.0, reach) if math.isfinite(reach) else 1.0
# Seconds between two judgements of where the room outshines the projector (room_dominated): health reports it only
# once it has lasted feelium.touch.sensing.HOLD_S, and judging it on every frame cost the share's per-tile map
# and two working-size passes a frame, on frames no candidate reads the share.
ROOM_JUDGE_INTERVAL_S = 0.2
# Seconds between two lessons of the fine pattern (feelium.touch.refine.FineDetail): it is static. Measured on the
# paper protocol at 15 fps, one lesson in 4 frames (0.27 s) and one in 2 kept a close hover's edge within 0.0005 of
# each other (0.0445), one in 8 let it rise to 0.0459 (full scale: 0.0430; this interval: 0.0438); a lesson costs
# ~0.6 ms of fine-resolution passes at 256x192.
DETAIL_INTERVAL_S = 0.25
# Seconds between two frames the projector's response (feelium.touch.photometric) learns from: about 15 a second,
# the rate of the recordings every accuracy figure was measured on (the paper's ~15 fps), so at the camera's 30 fps
# it learns as it did there. Why: its per-pixel sums were ~6 % of the touch thread's time at 30 fps (issue 16) for a
# memory of 20 s (``projected_response_tau_s``) solved every 0.2 s: every other frame adds little the fit can use.
# Three quarters of it count (a camera's frame times jitter): a 15 fps recording learns on every frame, as before,
# and 30 fps on every other frame. The share per place still learns on every frame: its short memory (0.5 s) follows
# a passer-by, and learned at 1/15 s it lost a tap of the lit room's seed 4 (docs/performance.md, session 14).
RESPONSE_LEARN_INTERVAL_S = 1.0 / 15.0
NOISE_TILES = (8, 6)
_SPECK_KERNEL = np.ones((3, 3), np.uint8)


def _noise_floor_map(signed_depth: np.ndarray, sigmas: float, minimum: float, scratch: Scratch) -> np.ndarray:
    """Per-pixel darkening floor: ``sigmas`` times the local noise of the smoothed depth, at least ``minimum``.

    Noise is measured per coarse tile from the negative half of the signed
    depth (shadows only add positive depth; for zero-mean gaussian noise the
    mean of min(d, 0)^2 is sigma^2 / 2), because relative noise is several
    times larger in the dim corners of an uneven back-light than at its centre.
    """
    h, w = signed_depth.shape
    negative = np.minimum(signed_depth, 0.0, out=scratch.like("floor.negative", signed_depth))
    negative *= negative
    tiles = cv2.resize(negative, NOISE_TILES, interpolation=cv2.INTER_AREA)
    np.sqrt(tiles * 2.0, out=tiles)
    tiles *= sigmas
    np.maximum(tiles, minimum, out=tiles)
    return cv2.resize(tiles, (w, h), dst=scratch.get("floor", (h, w), tiles.dtype), interpolation=cv2.INTER_LINEAR)


def _dilated(mask: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """``cv2.dilate(mask, kernel)`` (bool, a new array), computed only over the mask's bounding box widened by the
    kernel's reach: the same pixels to the bit (outside that box nothing can be set, and dilation's border counts
    as empty either way), at the cost of the shadow's box instead of the whole image (a hand's shadow is a small
    part of it, and the margin's ellipse is the costliest kernel the pipeline runs)."""
    bx, by, bw, bh = cv2.boundingRect(mask.view(np.uint8))
    ry, rx = kernel.shape[0] // 2, kernel.shape[1] // 2
    h, w = mask.shape
    y0, y1, x0, x1 = max(by - ry, 0), min(by + bh + ry, h), max(bx - rx, 0), min(bx + bw + rx, w)
    out = np.zeros(mask.shape, bool)
    part = np.ascontiguousarray(mask[y0:y1, x0:x1]).view(np.uint8)
    out[y0:y1, x0:x1] = cv2.dilate(part, kernel).view(bool)
    return out


def _regions_containing(mask: np.ndarray, seeds: list[tuple[float, float]]) -> np.ndarray:
    """The connected regions of ``mask`` that hold a seed point: a contact's whole shadow, penumbra included.

    Protecting the whole region (not only the candidate's deep part) keeps the
    forced update from eating a long press's shadow ring by ring.
    """
    h, w = mask.shape
    bx, by, bw, bh = cv2.boundingRect(mask.view(np.uint8))
    out = np.zeros(mask.shape, bool)
    if bw == 0:
        return out
    _, labels = cv2.connectedComponents(mask[by : by + bh, bx : bx + bw].view(np.uint8), connectivity=8)
    wanted = set()
    for sx, sy in seeds:
        ix = min(max(int(round(sx)) - bx, 0), bw - 1)
        iy = min(max(int(round(sy)) - by, 0), bh - 1)
        label = int(labels[iy, ix])
        if label:
            wanted.add(label)
    box = out[by : by + bh, bx : bx + bw]
    for label in wanted:
        box |= labels == label
    return out


# The darkest content the projected-light gate reads a press over as over the flat skin (relative to flat grey).
# Why a floor: dividing by the light present also multiplies a hover's noise by 1 / light, so over darker content
# the gate keeps at most twice the noise it was fitted against, and a press there reads ``f * light / 0.5``.
PRESENT_LIGHT_FLOOR = 0.5


def _present_light(light: np.ndarray | None, point: tuple[float, float]) -> float:
    """The projector's light present at ``point`` (detection image) relative to the flat skin's, in
    [:data:`PRESENT_LIGHT_FLOOR`, 1]; 1 without a predicted light (a static skin, the probe only).

    Why: the projector's share per place is learned against flat grey, so a press, which takes a fraction ``f`` of
    the projector's light *present*, takes ``f * light`` of the flat skin's: over the face's dark background
    (0.57 of flat) a press read 0.26 against the 0.2 gate and two taps of the whole face under a lit room were
    lost (docs/touch.md, *The whole face with the face on and the room lit*). A hand above the membrane takes
    none of the projector's light, at any light, so its reading stays at or under 0 (plus noise) either way."""
    if light is None:
        return 1.0
    h, w = light.shape[:2]
    x = min(max(int(round(point[0])), 0), w - 1)
    y = min(max(int(round(point[1])), 0), h - 1)
    value = float(light[y, x])
    return min(max(value, PRESENT_LIGHT_FLOOR), 1.0) if np.isfinite(value) else 1.0
