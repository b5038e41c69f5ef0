"""A recording's optional face model (meta["face"]): replay uses it; recordings without it are unchanged."""

import numpy as np
import pytest

from feelium.lab.touch.replay import face_of, replay_recording
from feelium.recording import Recording, RecordingError, RecordingWriter
from feelium.skin.face import FaceModel
from feelium.touch.config import TouchConfig
from tests.touch.synth import H, W, Patch, backlight, render

CFG = TouchConfig(width=W, height=H)
FACE = FaceModel.for_frame(W, H, fill=0.6)


def write(path, extra=None):
    rng = np.random.default_rng(5)
    light = backlight()
    frames = [render(light, rng=rng) for _ in range(10)]
    frames += [render(light, [Patch(14.0, 12.0, 0.75, 5.0)], rng=rng) for _ in range(8)]  # off the face
    frames += [render(light, rng=rng) for _ in range(8)]
    with RecordingWriter(path, name=path.name, width=W, height=H, fps=15.0, roi=(0, 0, W, H), extra_meta=extra) as w:
        for k, frame in enumerate(frames):
            w.add_frame(k / 15, frame)
    return Recording(path)


def test_replay_uses_the_face_model_of_the_recording(tmp_path):
    old = write(tmp_path / "rectangle")
    new = write(tmp_path / "face", {"face": FACE.to_json()})
    assert face_of(old) is None and face_of(new) == FACE
    assert replay_recording(old, CFG).events  # the rectangle takes the press
    assert replay_recording(new, CFG).events == []  # off the face: the black envelope of a real blimp


def test_a_bad_face_model_names_the_file_and_the_field(tmp_path):
    rec = write(tmp_path / "bad", {"face": {**FACE.to_json(), "focal_px": None}})
    with pytest.raises(RecordingError, match="focal_px"):
        face_of(rec)
    other = write(tmp_path / "other", {"face": FaceModel.for_frame(2 * W, 2 * H).to_json()})
    with pytest.raises(RecordingError, match="frames"):
        face_of(other)
