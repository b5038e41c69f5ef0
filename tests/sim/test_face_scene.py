"""The simulator's whole curved front face: back-light over the face, black envelope, hands at the local scale."""

import cv2
import numpy as np
import pytest

from feelium.sim.hand import HandPose
from feelium.sim.optics import face_backlight
from feelium.sim.scene import SceneRenderer, SceneState
from feelium.sim.sessions import session_presets
from feelium.skin.face import FaceModel

FACE = FaceModel.for_frame(320, 240)


@pytest.fixture(scope="module")
def scene():
    return SceneRenderer(session_presets(1)["s1"], np.random.default_rng(0), roi=FACE.roi(), face=FACE)


def test_the_back_light_covers_the_face_and_the_envelope_off_it_is_black(scene):
    lit = scene.backlight * scene.membrane
    on = FACE.mask()
    assert (scene.width, scene.height) == (FACE.width, FACE.height)
    assert float(scene.backlight[on].max()) == pytest.approx(session_presets(1)["s1"].optics.level, rel=1e-5)
    far_off = cv2.dilate(on.astype(np.uint8), np.ones((7, 7), np.uint8)) == 0  # beyond the rim's blur
    assert np.percentile(lit[far_off], 99) < 0.05 * np.median(lit[on])
    assert np.percentile(lit[on], 1) > 0.1 * np.median(lit[on])  # the whole face is lit, rim included


def test_the_back_light_falls_off_from_the_centre_to_the_rim():
    b = face_backlight(session_presets(1)["s1"].optics, FACE)
    u = np.linspace(0.02, 0.98, 25)
    rim = np.concatenate([
        np.stack(FACE.to_camera(u, np.full_like(u, 0.02)), 1), np.stack(FACE.to_camera(np.full_like(u, 0.02), u), 1),
    ])  # fmt: skip
    xs, ys = np.rint(rim[:, 0]).astype(int), np.rint(rim[:, 1]).astype(int)
    cx, cy = (int(round(float(c))) for c in FACE.to_camera(0.5, 0.5))
    assert b[ys, xs].max() < 0.8 * b[cy - 20 : cy + 21, cx - 20 : cx + 21].max()


def test_a_hand_is_drawn_at_the_local_scale_of_the_face(scene):
    def contact_area(u, v):
        x, y = (float(c) for c in FACE.to_camera(u, v))
        local = scene.local_shadow(x, y)
        assert local.px_per_mm == pytest.approx(float(FACE.px_per_mm(u, v)))
        found = scene.shadow(SceneState(hands=(HandPose(x, y, 0.0),)))
        return float(found.contact.sum()), local.px_per_mm

    centre, s0 = contact_area(0.5, 0.5)
    corner, s1 = contact_area(0.92, 0.9)
    assert s1 > 1.05 * s0  # the face's scale differs at the rim ...
    assert corner / centre == pytest.approx((s1 / s0) ** 2, rel=0.05)  # ... and the contact patch follows it


def test_without_a_face_the_renderer_is_the_flat_patch():
    session = session_presets(1)["s1"]
    a = SceneRenderer(session, np.random.default_rng(0))
    hand = SceneState(hands=(HandPose(300.0, 200.0, 0.0),))
    found = a.shadow(hand)
    parts, contacts = a.parts(hand)
    assert found.contact.sum() > 0 and len(contacts) == 1
    assert a.face is None
