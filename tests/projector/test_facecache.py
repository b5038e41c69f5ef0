"""The wearer's faces kept decoded: a looping avatar decoded once per frame, the same pictures, within the budget."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from feelium.daemon.config import Config
from feelium.hub import Hub
from feelium.projector.display import SimDisplay
from feelium.projector.facecache import DecodedFaces
from feelium.projector.service import ProjectorService
from tests.projector.helpers import truth_calibration


def _jpeg(level: int) -> bytes:
    image = np.full((360, 480, 3), level, np.uint8)
    cv2.circle(image, (240, 180), 60 + level // 8, (90, 140, 220), -1)
    return cv2.imencode(".jpg", image)[1].tobytes()


def _service(now: list[float], cache_mb: float) -> tuple[Hub, ProjectorService]:
    hub = Hub(clock=lambda: now[0])
    config = dataclasses.replace(Config().projector, face_cache_mb=cache_mb)
    return hub, ProjectorService(config, Config().interactions, hub, SimDisplay(), truth_calibration())


async def _play(hub: Hub, service: ProjectorService, now: list[float], loop: list[bytes], rounds: int) -> list[np.ndarray]:
    shown = []
    for k in range(rounds * len(loop)):
        now[0] += 1 / 12
        hub.face.publish(hub.clock(), loop[k % len(loop)])
        service.update_face()
        assert service._face is not None
        shown.append(service._face)
    return shown


async def test_a_looping_avatar_is_decoded_once_per_frame_and_shows_the_same_pictures():
    loop = [_jpeg(level) for level in (40, 90, 140)]
    now = [0.0]
    hub, service = _service(now, 16.0)
    shown = await _play(hub, service, now, loop, rounds=3)
    assert service.counters["faces"] == 9 and service.health()["faces_decoded"] == 6  # kept when it came round
    assert service.health()["faces_kept_mb"] == pytest.approx(3 * 512 * 384 * 3 / 2**20, abs=0.1)
    uncached_hub, uncached = _service([0.0], 0.0)
    again = await _play(uncached_hub, uncached, [0.0], loop, rounds=3)
    assert uncached.health()["faces_decoded"] == 9  # nothing kept: every showing decoded, as before
    for face, reference in zip(shown, again):
        assert np.array_equal(face, reference)
    assert shown[6] is shown[3]  # the kept array itself, round after round
    assert not any(face.flags.writeable for face in shown)  # the renderer's "same array, same picture" holds
    hub.face.publish(hub.clock(), None)  # the wearer cleared the face: the kept faces go too
    service.update_face()
    assert service._face is None and service.health()["faces_kept_mb"] == 0.0


def _seen_twice(faces: DecodedFaces, jpeg: bytes, face: np.ndarray, now: float) -> None:
    faces.put(jpeg, face.copy(), now - 0.01)  # decoded once: only noted
    faces.put(jpeg, face.copy(), now)  # came round: kept if it fits


def test_a_face_is_kept_the_second_time_within_the_budget_and_unused_faces_are_let_go():
    face = np.zeros((10, 10, 3), np.uint8)  # 300 bytes
    faces = DecodedFaces(max_bytes=700, idle_s=5.0)
    faces.put(b"once", face.copy(), 0.0)  # a single JPEG shown once (a stream of them): nothing kept
    assert len(faces) == 0 and faces.bytes == 0
    _seen_twice(faces, b"a", face, 0.0)
    _seen_twice(faces, b"b", face, 1.0)
    _seen_twice(faces, b"c", face, 2.0)  # over the budget, and nothing is idle yet: not kept
    assert len(faces) == 2 and faces.bytes == 600
    assert faces.get(b"c", 2.0) is None and faces.get(b"b", 5.5) is not None
    _seen_twice(faces, b"c", face, 6.0)  # "a" was last shown at 0.0: let go; "b" (5.5) stays
    assert faces.get(b"a", 6.0) is None and faces.get(b"b", 6.0) is not None and faces.get(b"c", 6.0) is not None
    assert faces.bytes == 600
    _seen_twice(faces, b"d", np.zeros((2, 2, 3), np.uint8), 20.0)  # a loop long after: the old loop's faces go
    assert len(faces) == 1 and faces.bytes == 12
    faces.clear()
    assert len(faces) == 0 and faces.bytes == 0


def test_only_jpeg_bytes_are_kept_and_what_is_handed_back_is_read_only():
    faces = DecodedFaces(max_bytes=10**6)
    array_face = np.zeros((4, 4, 3), np.uint8)
    kept = faces.put(np.zeros(3), array_face, 0.0)  # a face handed as an image (not bytes): used, not kept
    assert kept is array_face and not kept.flags.writeable and len(faces) == 0
    assert faces.get(np.zeros(3), 0.0) is None
    with pytest.raises(ValueError):
        kept[0, 0, 0] = 1
