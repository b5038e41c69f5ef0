"""The projector service end to end on a hub: touch in, wearer's event out, answer on the projected frame."""

from __future__ import annotations

import asyncio
import dataclasses
import threading
import time

import cv2
import numpy as np
import pytest

from feelium.daemon.config import Config
from feelium.events import InteractionEvent, WearerAction
from feelium.hub import Hub
from feelium.motion import MAX_HOLD_S
from feelium.projector.display import SimDisplay
from feelium.daemon.assembly import build_projector
from feelium.projector.service import ProjectorService
from feelium.skin.projector_map import calibration_path, load_or_default
from tests.interactions.touches import at_uv, tap
from tests.projector.helpers import centroid, truth_calibration


async def _until(predicate, timeout=10.0):
    deadline = asyncio.get_running_loop().time() + timeout
    while not predicate():
        if asyncio.get_running_loop().time() > deadline:
            raise AssertionError("condition not reached in time")
        await asyncio.sleep(0.02)


@pytest.fixture
async def running():
    hub = Hub()
    service = ProjectorService(Config().projector, Config().interactions, hub, SimDisplay(), truth_calibration())
    task = asyncio.create_task(service.run())
    yield hub, service
    await service.stop()
    await asyncio.wait_for(task, 5.0)


async def test_a_peck_reaches_the_wearer_and_the_heart_lands_on_the_cheek(running):
    hub, service = running
    events = hub.bus.subscribe([InteractionEvent])
    await _until(lambda: hub.projector_video.get() is not None)
    x, y = at_uv(0.73, 0.58)
    now = hub.clock()
    for e in tap(1, now, x, y):
        hub.bus.publish(dataclasses.replace(e, t=e.t))
    await _until(lambda: service.counters["interaction_events"] >= 1)
    got = events.drain()
    assert [(e.name, e.phase, e.region) for e in got] == [("peck", "bloom", "cheek_right")]
    assert got[0].to_json()["x"] == pytest.approx(x)
    seq = hub.projector_video.get().seq
    await _until(lambda: hub.projector_video.get().seq > seq + 3)
    item = hub.projector_video.get()
    frame = item.value
    # The avatar without answers at the instant the frame was drawn: up to 1 / answer_fps before the display got it
    # (a frame with nothing new is the previous one), later still on a loaded machine.
    befores = [service.renderer.render(item.t - k / 30, None, []) for k in range(4)]
    diffs = [np.abs(frame.astype(np.int16) - before.astype(np.int16)).sum(axis=2) for before in befores]
    diff = min(diffs, key=lambda d: int((d >= 60).sum()))
    diff[diff < 60] = 0
    expected = truth_calibration().to_projector(x, y)
    got_xy = centroid(diff)
    assert np.hypot(got_xy[0] - expected[0], got_xy[1] - expected[1]) < 20.0


async def test_motion_replies_use_the_dead_man_path_but_never_override_the_wearer(running):
    hub, service = running
    hub.bus.publish(WearerAction("shimmer", hub.clock()))
    await _until(lambda: service.counters["motions_sent"] >= 1)
    cmd = hub.motion.active(hub.clock())
    assert cmd is not None and cmd.name == "forward" and cmd.source == "interaction"
    hub.motion.command("turn_left", hub.clock(), MAX_HOLD_S, source="headset")
    hub.bus.publish(tap(1, hub.clock(), *at_uv(0.5, 0.5))[0])  # accepts the invite: a bounce is due
    await _until(lambda: service.counters["motions_skipped"] >= 1)
    assert hub.motion.active(hub.clock()).name == "turn_left"


async def test_face_jpeg_is_shown_and_a_broken_one_is_counted(running):
    hub, service = running
    face = np.zeros((240, 320, 3), np.uint8)
    face[:] = (0, 220, 0)
    ok, jpeg = cv2.imencode(".jpg", face)
    await _until(lambda: hub.projector_video.get() is not None)  # the render thread took up its first frames
    hub.face.publish(hub.clock(), jpeg.tobytes())
    await _until(lambda: service.counters["faces"] == 1)
    seq = hub.projector_video.get().seq
    await _until(lambda: hub.projector_video.get().seq > seq + 1)
    assert hub.projector_video.get().value[360, 640, 1] > 200
    hub.face.publish(hub.clock(), b"not a jpeg")
    await _until(lambda: service.counters["bad_faces"] == 1)
    assert service.health()["frames"] > 0 and service.health()["display"] == "sim"


async def test_a_single_face_stays_however_long_the_headset_is_quiet_until_cleared():
    now = [100.0]
    hub = Hub(clock=lambda: now[0])
    service = ProjectorService(Config().projector, Config().interactions, hub, SimDisplay(), truth_calibration())
    ok, jpeg = cv2.imencode(".jpg", np.full((240, 320, 3), 200, np.uint8))
    hub.face.publish(hub.clock(), jpeg.tobytes())
    service.update_face()
    assert service._face is not None and service.counters["faces"] == 1
    now[0] += 3600.0  # an hour without another upload (it used to vanish after 3 s)
    service.update_face()
    assert service._face is not None
    hub.face.publish(hub.clock(), None)  # DELETE /api/v1/face
    service.update_face()
    assert service._face is None and service.counters["bad_faces"] == 0


def test_build_projector_without_calibration_uses_the_default_map(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    config = Config()
    config = dataclasses.replace(config, projector=dataclasses.replace(config.projector, backend="sim"))
    service = build_projector(config, Hub())
    assert service.name == "projector" and service.calibration.source == "default"
    truth_calibration().save(tmp_path / "projector_calibration.npz")
    size = (config.projector.width, config.projector.height)
    assert load_or_default(calibration_path(config.projector.calibration.file), size, None).source == "truth"


def test_the_daemon_holds_one_calibration_for_the_projector_and_touch(tmp_path):
    """The projector's renderer, the touch annotation and the light predictor share one map (was three)."""
    import gc

    from feelium.daemon.assembly import load_projected_light, load_projector_annotation

    path = truth_calibration().save(tmp_path / "projector_calibration.npz")
    config = Config()
    config = dataclasses.replace(
        config,
        projector=dataclasses.replace(
            config.projector, backend="sim", calibration=dataclasses.replace(config.projector.calibration, file=str(path))
        ),
        rear_camera=dataclasses.replace(config.rear_camera, projection_compensation="on"),
    )
    def maps() -> set[int]:
        gc.collect()
        return {id(o) for o in gc.get_objects() if type(o).__name__ == "ProjectorMap"}

    before = maps()  # whatever earlier tests left alive
    service = build_projector(config, Hub())
    annotation = load_projector_annotation(config)
    projected = load_projected_light(config, "sim")
    assert annotation is not None and projected is not None
    assert annotation.calibration is service.calibration
    assert maps() - before == {id(service.calibration)}  # the predictor's factory holds that one too, no copy
    assert not service.calibration.proj_x.flags.writeable


def test_the_renderer_keeps_no_blank_or_coverage_frame(tmp_path):
    """Full-size arrays a renderer keeps are its pooled frames only (a 2.7 MB blank and a 0.9 MB coverage mask
    were kept for the daemon's whole life before)."""
    from feelium.projector.renderer import Renderer

    config = Config().projector
    calibration = truth_calibration()
    renderer = Renderer(config, calibration)
    renderer.render(0.0, None, [])
    pooled = {id(b.array) for b in renderer.tiles._pool}
    kept = [
        (owner, name) for owner in (renderer, renderer.tiles) for name, value in vars(owner).items()
        if isinstance(value, np.ndarray) and value.shape[:2] == (config.height, config.width) and id(value) not in pooled
    ]
    assert kept == []
    assert renderer.covered.shape == (config.height, config.width) and renderer.covered.dtype == bool
    assert renderer.covered.any() and not renderer.covered.all()


class _SlowDisplay(SimDisplay):
    """Takes three frame periods to show a frame."""

    def show(self, frame: np.ndarray) -> None:
        import time

        time.sleep(0.1)
        super().show(frame)


async def test_a_frame_slower_than_its_period_is_counted_late():
    hub = Hub()
    config = dataclasses.replace(Config().projector, fps=30.0)
    display = _SlowDisplay()
    service = ProjectorService(config, Config().interactions, hub, display, truth_calibration())
    task = asyncio.create_task(service.run())
    await _until(lambda: display.frames >= 3)
    await service.stop()
    await asyncio.wait_for(task, 5.0)
    assert service.counters["late_frames"] >= 2 and service.health()["late_frames"] == service.counters["late_frames"]


class _ThreadRecordingDisplay(SimDisplay):
    """Notes which thread each frame is shown from (rendering and showing run in one job)."""

    def __init__(self) -> None:
        super().__init__()
        self.threads: set[str] = set()

    def show(self, frame: np.ndarray) -> None:
        self.threads.add(threading.current_thread().name)
        super().show(frame)


async def test_every_frame_is_rendered_on_the_projectors_own_thread_while_the_shared_pool_is_busy():
    """OpenCV 5 keeps a ~5.7 MB font cache in each thread that draws text: one rendering thread holds one,
    where the loop's shared pool had each of its threads take a turn (and hold one)."""
    hub = Hub()
    display = _ThreadRecordingDisplay()
    service = ProjectorService(Config().projector, Config().interactions, hub, display, truth_calibration())
    task = asyncio.create_task(service.run())
    busy = [asyncio.create_task(asyncio.to_thread(time.sleep, 0.05)) for _ in range(8)]  # the pool's threads exist
    await _until(lambda: service.counters["frames"] >= 12)
    await asyncio.gather(*busy)
    await service.stop()
    await asyncio.wait_for(task, 5.0)
    assert display.threads == {"projector-render_0"}


class _ClosingDisplay(SimDisplay):
    """Notes a frame shown after the display was closed."""

    def __init__(self, fail_at: int | None = None) -> None:
        super().__init__()
        self.closed = False
        self.shown_after_close = 0
        self.fail_at = fail_at

    def show(self, frame: np.ndarray) -> None:
        if self.fail_at is not None and self.frames == self.fail_at:
            raise OSError("framebuffer gone")
        self.shown_after_close += self.closed
        super().show(frame)

    def close(self) -> None:
        self.closed = True
        super().close()


def _render_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("projector-render")]


async def test_frames_go_on_while_the_event_loop_is_blocked_and_stop_ends_the_thread():
    """The render thread keeps its own 30 fps clock: a loop blocked for 0.3 s (a burst, a CPU quota) does not
    hold frames up, and the loop is not woken for them."""
    hub = Hub()
    display = _ClosingDisplay()
    service = ProjectorService(Config().projector, Config().interactions, hub, display, truth_calibration())
    task = asyncio.create_task(service.run())
    await _until(lambda: service.counters["frames"] >= 3)
    before = service.counters["frames"]
    time.sleep(0.3)  # the event loop blocked: 9 frame periods
    assert service.counters["frames"] - before >= 4
    assert hub.projector_video.get().seq == service.counters["frames"]  # published without the loop too
    await service.stop()
    await asyncio.wait_for(task, 5.0)
    frames = service.counters["frames"]
    await asyncio.sleep(0.1)
    assert service.counters["frames"] == frames and display.closed and display.shown_after_close == 0
    for thread in _render_threads():
        thread.join(1.0)
    assert _render_threads() == []


async def test_a_cancelled_run_closes_the_display_after_the_threads_last_frame():
    hub = Hub()
    display = _ClosingDisplay()
    service = ProjectorService(Config().projector, Config().interactions, hub, display, truth_calibration())
    task = asyncio.create_task(service.run())
    await _until(lambda: service.counters["frames"] >= 3)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    frames = service.counters["frames"]
    await asyncio.sleep(0.1)
    assert service.counters["frames"] == frames and display.closed and display.shown_after_close == 0


async def test_a_display_error_ends_the_run_for_the_supervisor_to_restart():
    """The error reaches run() (the supervisor logs it and restarts the service); the display is closed."""
    hub = Hub()
    display = _ClosingDisplay(fail_at=3)
    service = ProjectorService(Config().projector, Config().interactions, hub, display, truth_calibration())
    with pytest.raises(OSError, match="framebuffer gone"):
        await asyncio.wait_for(service.run(), 5.0)
    assert service.counters["frames"] == 3 and display.closed
    display.fail_at = None
    task = asyncio.create_task(service.run())  # the restart renders again
    await _until(lambda: service.counters["frames"] >= 6)
    await service.stop()
    await asyncio.wait_for(task, 5.0)
