"""What the rear camera sees: back-light x membrane x shadow, through the sensor.

    value = clip(round(gain(t) * exposure(t) * B(x, y, t) * T(x, y) * S(x, y, t) + noise), 0, 255)

``B`` is the session's back-light (times laser banding and, when the projector
helper supplies one, a projected image's factor), ``T`` the membrane, ``S`` the
shadow of whatever is outside (hands, a body) and ``exposure`` a script's own
exposure change (auto-exposure hunting in an empty scene). Given a
:class:`feelium.skin.face.FaceModel`, the membrane is the whole curved front
face: back-light over the face, envelope black off it, and each hand drawn at
the local scale (px per mm) of the face where its fingertip is. The renderer is
pure: camera time and scene state in, an 8-bit frame out; its only state is the
RNG that draws the noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from feelium.sim.body import Lean
from feelium.sim.camera import SensorParams, expose, gain_at
from feelium.sim.hand import Blob, HandPose, hand_parts
from feelium.sim.optics import OpticsParams, backlight, face_backlight, laser_banding, membrane_transmission
from feelium.sim.room import AutoExposure, RoomLight, lamp_image
from feelium.sim.shadow import Ellipse, Part, Shadow, ShadowParams, render_shadow
from feelium.skin.face import FaceModel

WIDTH, HEIGHT = 640, 480
ROI = (64, 48, 512, 384)

Projected = Callable[[float], "np.ndarray | None"]


@dataclass(frozen=True)
class Session:
    """Conditions shared by every recording of one session: projector, membrane, room and camera."""

    name: str
    optics: OpticsParams = field(default_factory=OpticsParams)
    shadow: ShadowParams = field(default_factory=ShadowParams)
    sensor: SensorParams = field(default_factory=SensorParams)
    membrane_seed: int = 0  # the membrane texture is the same physical skin in every session
    ambient_c: float = 22.0  # room temperature, for the thermal channel

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "optics": self.optics.to_json(),
            "shadow": vars(self.shadow).copy(),
            "sensor": self.sensor.to_json(),
            "membrane_seed": self.membrane_seed,
            "ambient_c": self.ambient_c,
        }


@dataclass(frozen=True)
class SceneState:
    """Everything outside the membrane at one instant."""

    hands: tuple[HandPose, ...] = ()
    blobs: tuple[Blob, ...] = ()
    leans: tuple[Lean, ...] = ()  # bodies leaning in (hugs)
    room: float = 1.0  # outside light level relative to the session's (1 = as calibrated)
    exposure: float = 1.0  # extra exposure factor (auto-exposure hunting), 1 = none


class SceneRenderer:
    """Renders camera frames of one session's scene; ``projected`` is the projector helper's hook."""

    def __init__(
        self,
        session: Session,
        rng: np.random.Generator,
        *,
        width: int = WIDTH,
        height: int = HEIGHT,
        roi: tuple[int, int, int, int] = ROI,
        projected: Projected | None = None,
        gain_phase: float | None = None,
        projected_share_only: bool = False,
        room_light: RoomLight | None = None,
        face: FaceModel | None = None,
    ) -> None:
        """``projected_share_only``: the projected factor scales only the projector's share of the membrane's
        light (``1 - outside_share``), not the room light coming in through it (the physical model; the
        default scales both, as the projector experiments were built on). ``room_light``: a lit room's own
        light through the membrane (:mod:`feelium.sim.room`), with the camera's auto-exposure following it;
        frames must then be asked for in time order. ``face``: the whole curved front face (its frame size wins
        over ``width``/``height``), see the module docstring."""
        if face is not None:
            width, height = face.width, face.height
        self.face = face
        self.session = session
        self.width, self.height, self.roi = width, height, roi
        self._rng = rng
        self._projected = projected
        self._share_only = projected_share_only
        on_face = None if face is None else face.mask()
        self.backlight = backlight(session.optics, width, height, roi) if face is None else face_backlight(session.optics, face)
        self.membrane = membrane_transmission(
            session.optics, width, height, roi, np.random.default_rng(session.membrane_seed), face=on_face
        )
        self._lit = (self.backlight * self.membrane).astype(np.float32)
        self._gain_phase = float(rng.uniform(0, 2 * np.pi)) if gain_phase is None else gain_phase
        self._room = room_light
        if room_light is not None:
            self._lamp = lamp_image(self.backlight, self.membrane, roi, room_light.gradient, room_light.gradient_angle_deg)
            self._exposure = AutoExposure(room_light, width)

    def parts(self, state: SceneState) -> tuple[list[Part], list[Ellipse]]:
        parts: list[Part] = []
        contacts: list[Ellipse] = []
        for hand in state.hands:
            p, c = hand_parts(hand, self.session.shadow.px_per_mm)
            parts += p
            contacts += c
        for blob in state.blobs:
            parts += blob.parts()
        for lean in state.leans:
            p, c = lean.parts(self.session.shadow.px_per_mm)
            parts += p
            contacts += c
        return parts, contacts

    def local_shadow(self, x: float, y: float) -> ShadowParams:
        """The session's shadow parameters at camera pixel ``(x, y)`` of the face: its local px per mm.

        A hand is drawn at the scale where its fingertip is (a hand spans a few
        degrees of the face, over which the scale changes by a few per cent).
        """
        assert self.face is not None
        u, v = self.face.to_uv(x, y)
        scale = float(self.face.px_per_mm(np.clip(np.nan_to_num(u, nan=0.5), 0, 1), np.clip(np.nan_to_num(v, nan=0.5), 0, 1)))
        return replace(self.session.shadow, px_per_mm=scale)

    def shadow(self, state: SceneState) -> Shadow:
        """Occlusion and contact of everything outside: in one pass on the flat patch, hand by hand on the face."""
        s = self.session
        if self.face is None:
            parts, contacts = self.parts(state)
            return render_shadow(parts, contacts, s.shadow, self.width, self.height)
        centre = self.local_shadow(*(float(c) for c in self.face.to_camera(0.5, 0.5)))
        blobs = [part for blob in state.blobs for part in blob.parts()]
        found = render_shadow(blobs, [], centre, self.width, self.height)
        for hand in state.hands:
            local = self.local_shadow(hand.x, hand.y)
            parts, contacts = hand_parts(hand, local.px_per_mm)
            one = render_shadow(parts, contacts, local, self.width, self.height)
            np.maximum(found.occlusion, one.occlusion, out=found.occlusion)
            np.maximum(found.contact, one.contact, out=found.contact)
        return found

    def signal(self, t: float, state: SceneState | Sequence[SceneState]) -> np.ndarray:
        """The noiseless signal in DN (H, W) float32 at camera time ``t``.

        ``state`` may be several sub-samples across the exposure (see :func:`exposure_samples`):
        their shadows are averaged, which is the motion blur of a moving hand.
        """
        states = [state] if isinstance(state, SceneState) else list(state)
        s = self.session
        mid = states[len(states) // 2]
        gain = gain_at(s.sensor, t, self._gain_phase) * mid.exposure
        image = self._lit * laser_banding(s.optics, self.height, t)
        factor = self._projected(t) if self._projected is not None else None
        if factor is not None:
            if factor.shape != (self.height, self.width):
                raise ValueError(f"projected factor is {factor.shape}, camera is {(self.height, self.width)}")
            factor = factor.astype(np.float32, copy=False)
        lit: float | np.ndarray = 1.0
        if factor is not None and self._share_only:
            lit = factor
        elif factor is not None:
            image = image * factor
        transmission: np.ndarray | None = None
        open_sky: np.ndarray | None = None  # mean over sub-samples of 1 - occlusion (the room light let through)
        for sub in states:
            if not (sub.hands or sub.blobs or sub.leans or sub.room != 1.0):
                continue
            found = self.shadow(sub)
            shadow = found.lit_by(s.shadow, sub.room, lit)
            transmission = shadow if transmission is None else transmission + shadow
            if self._room is not None:
                free = 1.0 - found.occlusion
                open_sky = free if open_sky is None else open_sky + free
        unshadowed = len(states) - sum(1 for sub in states if sub.hands or sub.blobs or sub.leans or sub.room != 1.0)
        if transmission is not None or not isinstance(lit, float):
            clear = s.shadow.outside_share + (1.0 - s.shadow.outside_share) * lit
            total = clear * unshadowed if transmission is None else transmission + clear * unshadowed
            image = image * (total / len(states))
        if self._room is not None:
            image = image + self._room_term(t, open_sky, unshadowed, len(states))
            gain *= self._exposure.at(t)
        return image * np.float32(gain)

    def _room_term(self, t: float, open_sky: np.ndarray | None, unshadowed: int, samples: int) -> np.ndarray:
        """The lit room's light reaching the camera at ``t``: level x lamp image x what hands and a passer let through."""
        assert self._room is not None
        term = self._lamp * np.float32(self._room.level_at(t))
        if open_sky is not None:
            term = term * ((open_sky + np.float32(unshadowed)) / np.float32(samples))
        if self._room.passer is not None:
            loss = self._room.passer.occlusion(t, self.width)
            if loss is not None:
                term = term * (1.0 - loss)[None, :]
        return term

    def frame(self, t: float, state: SceneState | Sequence[SceneState]) -> np.ndarray:
        """One 8-bit camera frame (H, W) uint8 at camera time ``t``."""
        return expose(self.signal(t, state), self.session.sensor, self._rng)


def exposure_samples(
    state_at: Callable[[float], SceneState], t: float, exposure_s: float, *, px_per_step: float = 3.0, most: int = 4
) -> list[SceneState]:
    """Scene sub-samples across the exposure centred on ``t``: one when still, up to ``most`` when moving.

    A fingertip that moves ``d`` px during the exposure gets ``ceil(d / px_per_step)``
    samples, so a fast swipe smears as it does on the sensor while still frames cost nothing extra.
    """
    mid = state_at(t)
    if exposure_s <= 0.0 or not mid.hands:
        return [mid]
    start, end = state_at(t - exposure_s / 2), state_at(t + exposure_s / 2)
    travel = 0.0
    for a, b in zip(start.hands, end.hands):
        travel = max(travel, math.hypot(b.x - a.x, b.y - a.y))
    n = min(most, max(1, math.ceil(travel / px_per_step)))
    if n == 1:
        return [mid]
    return [state_at(t - exposure_s / 2 + exposure_s * (i + 0.5) / n) for i in range(n)]
