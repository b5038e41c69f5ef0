"""The touch service shell: frames through the pipeline to the bus, bad frames counted, debug view, state."""

from __future__ import annotations

import asyncio
import dataclasses
import time
from dataclasses import dataclass

import numpy as np
import pytest

from feelium.cameras.base import Frame
from feelium.cameras.select import CameraSource
from feelium.events import TouchEvent
from feelium.hub import Hub
from feelium.touch.config import TouchConfig
from feelium.touch.geometry import LightGrids
from feelium.touch.service import TouchService


@dataclass(frozen=True)
class FakeContact:
    id: int
    x: float
    y: float
    depth: float


@dataclass(frozen=True)
class FakeResult:
    t: float
    events: tuple
    activity: bool
    anchor: float
    depth_max: float
    area: int
    contacts: tuple


def _event(t: float, phase: str) -> TouchEvent:
    return TouchEvent(id=1, phase=phase, kind=None, t=t, x=5.0, y=6.0, u=0.5, v=0.5, depth=0.5, area=10, anchor=1.0)


class FakePipeline:
    """Emits a down on its 2nd frame; rejects non-increasing times like the real one; 'explodes' on demand."""

    created: list["FakePipeline"] = []

    def __init__(self, config, size, roi):
        self.size, self.roi = size, roi
        self.times: list[float] = []
        self.finished = False
        FakePipeline.created.append(self)

    def process(self, t, frame):
        if self.times and t <= self.times[-1]:
            raise ValueError(f"frame time {t} does not follow {self.times[-1]}")
        if frame[0, 0] == 13:
            raise RuntimeError("pipeline bug")
        self.times.append(t)
        events = (_event(t, "down"),) if len(self.times) == 2 else ()
        contacts = (FakeContact(1, 5.0, 6.0, 0.5),) if len(self.times) >= 2 else ()
        return FakeResult(t, events, bool(contacts), 0.9, 0.5, 10, contacts)

    def finish(self):
        self.finished = True
        return (_event(self.times[-1], "up"),) if len(self.times) >= 2 else ()


class ScriptedCamera:
    name = "scripted"
    realtime = False

    def __init__(self, frames, delay=0.0):
        self.frames = list(frames)
        self.closed = False
        self.delay = delay  # seconds each read takes (lets the event loop run between frames)

    def read(self):
        if self.delay:
            time.sleep(self.delay)
        return self.frames.pop(0) if self.frames else None

    def close(self):
        self.closed = True


def _frame(t, segment=0, value=100, size=(8, 6), roi=(1, 1, 4, 4)):
    return Frame(t=t, image=np.full((size[1], size[0]), value, np.uint8), segment=segment, roi=roi)


def _overlay(frame, result, roi):
    out = np.zeros((*frame.shape[:2], 3), np.uint8)
    out[...] = len(result.contacts)
    return out


def _service(frames, hub, **kwargs):
    camera = ScriptedCamera(frames)
    service = TouchService(
        CameraSource("scripted", lambda: camera), hub, TouchConfig(), pipeline_factory=FakePipeline, overlay=_overlay, **kwargs
    )
    return service, camera


@pytest.fixture(autouse=True)
def _fresh():
    FakePipeline.created.clear()


async def test_events_reach_the_bus_and_the_state_board():
    hub = Hub()
    sub = hub.bus.subscribe([TouchEvent])
    service, camera = _service([_frame(0.1 * i) for i in range(1, 5)], hub)
    await service.run()
    events = sub.drain()
    assert [(e.phase, e.t) for e in events] == [("down", pytest.approx(0.2)), ("up", pytest.approx(0.4))]
    assert FakePipeline.created[0].finished  # contacts still down are released when the source ends
    state = hub.state.snapshot()["touch"]
    assert state["contacts"] == [{"id": 1, "x": 5.0, "y": 6.0, "depth": 0.5}]
    assert state["activity"] is True and state["backend"] == "scripted"
    health = service.health()
    assert health["frames"] == 4 and health["events"] == 2 and health["bad_frames"] == 0
    assert health["last_frame_at"] is not None and camera.closed


async def test_each_frame_wakes_the_event_loop_once():
    """Camera to pipeline thread to thread; the loop is woken only to publish (a batch, if it lags)."""
    hub = Hub()
    camera = ScriptedCamera([_frame(0.1 * i) for i in range(1, 11)], delay=0.005)
    service = TouchService(CameraSource("s", lambda: camera), hub, TouchConfig(), pipeline_factory=FakePipeline, overlay=_overlay)
    await service.run()
    health = service.health()
    assert health["frames"] == 10
    assert 11 >= health["loop_wakeups"] >= 1  # at most one per frame, plus the contacts released at the end


async def test_bad_frames_are_counted_and_skipped():
    hub = Hub()
    frames = [
        _frame(0.1),
        _frame(0.1),  # repeated time: the pipeline's ValueError
        Frame(t=0.2, image=np.zeros((6, 8, 4), np.uint8)),  # wrong shape
        Frame(t=0.25, image=np.zeros((6, 8), np.float32)),  # wrong dtype
        _frame(0.3),
    ]
    service, _ = _service(frames, hub)
    await service.run()
    health = service.health()
    assert health["frames"] == 2 and health["bad_frames"] == 3
    assert "uint8" in health["last_bad_frame"]


async def test_a_pipeline_bug_crashes_the_service_for_the_supervisor_to_restart():
    hub = Hub()
    service, camera = _service([_frame(0.1), _frame(0.2, value=13), _frame(0.3)], hub)
    with pytest.raises(RuntimeError, match="pipeline bug"):
        await service.run()
    assert camera.closed


async def test_a_new_segment_or_frame_size_gets_a_fresh_pipeline_and_releases_open_contacts():
    hub = Hub()
    sub = hub.bus.subscribe([TouchEvent])
    frames = [_frame(0.1), _frame(0.2), _frame(0.3, segment=1), _frame(0.4, segment=1, size=(10, 8), roi=None)]
    service, _ = _service(frames, hub)
    await service.run()
    sizes = [(p.size, p.roi) for p in FakePipeline.created]
    assert sizes == [((8, 6), (1, 1, 4, 4)), ((8, 6), (1, 1, 4, 4)), ((10, 8), None)]
    assert [e.phase for e in sub.drain()] == ["down", "up"]


async def test_debug_view_is_published_at_its_own_modest_rate():
    hub = Hub()
    service, _ = _service([_frame(0.05 * i) for i in range(1, 41)], hub, debug_video_fps=5.0)  # 2 s at 20 fps
    await service.run()
    assert 9 <= hub.rear_video.published <= 11
    assert hub.rear_video.get().value.shape == (6, 8, 3)
    quiet, _ = _service([_frame(0.05 * i) for i in range(1, 10)], Hub(), debug_video_fps=0.0)
    await quiet.run()
    assert quiet.hub.rear_video.published == 0


async def test_stop_ends_a_running_service():
    class Endless(ScriptedCamera):
        realtime = True

        def __init__(self):
            super().__init__([])
            self.t = 0.0

        def read(self):
            import time

            time.sleep(0.005)
            self.t += 0.01
            return _frame(self.t)

    hub = Hub()
    camera = Endless()
    service = TouchService(CameraSource("endless", lambda: camera), hub, TouchConfig(), pipeline_factory=FakePipeline, overlay=_overlay)
    task = asyncio.create_task(service.run())
    while service.frames < 3:
        await asyncio.sleep(0.01)
    await service.stop()
    await asyncio.wait_for(task, 2.0)
    assert camera.closed


async def test_a_failing_overlay_costs_only_the_debug_view():
    def broken(frame, result, roi):
        raise ImportError("no overlay yet")

    hub = Hub()
    camera = ScriptedCamera([_frame(0.1 * i) for i in range(1, 5)])
    service = TouchService(CameraSource("s", lambda: camera), hub, TouchConfig(), pipeline_factory=FakePipeline, overlay=broken)
    await service.run()
    health = service.health()
    assert health["frames"] == 4 and health["overlay_errors"] >= 1
    assert "no overlay yet" in health["last_overlay_error"] and hub.rear_video.published == 0


def _calibration(camera_size=(32, 24), roi=(4, 4, 24, 16), projector_size=(64, 48)):
    from feelium.skin.projector_map import default_calibration

    return default_calibration(camera_size, roi, projector_size)


def _config_with_calibration_file(path):
    import dataclasses

    from feelium.daemon.config import Config

    base = Config()
    calibration = dataclasses.replace(base.projector.calibration, file=str(path))
    return dataclasses.replace(base, projector=dataclasses.replace(base.projector, calibration=calibration))


async def test_with_a_projector_calibration_events_gain_projector_coordinates_and_region():
    from feelium.interactions.config import InteractionsConfig
    from feelium.skin.regions import Regions
    from feelium.skin.annotation import ProjectorAnnotation

    calibration = _calibration()  # at twice the frames' resolution: events are scaled onto it
    annotation = ProjectorAnnotation(calibration, Regions.from_config(InteractionsConfig()))
    hub = Hub()
    sub = hub.bus.subscribe([TouchEvent])
    frames = [_frame(0.1 * i, size=(16, 12), roi=(2, 2, 12, 8)) for i in range(1, 4)]
    service, _ = _service(frames, hub, annotation=annotation)
    await service.run()
    events = sub.drain()
    assert [e.phase for e in events] == ["down", "up"]
    px, py = calibration.to_projector(10.0, 12.0)  # the event's (5, 6) in the calibration's camera pixels
    for event in events:
        assert (event.x, event.y) == (5.0, 6.0)  # camera coordinates are left as they were
        assert event.extra["px"] == pytest.approx(px, abs=0.05) and event.extra["py"] == pytest.approx(py, abs=0.05)
        assert event.extra["region"] == "cheek_left"  # u = 0.25, v = 0.5 on the calibrated patch
        assert event.to_json()["region"] == "cheek_left"
    assert service.health()["projector_annotation"] == {"errors": 0, "last_error": None}


async def test_without_a_calibration_file_events_pass_unchanged(tmp_path):
    from feelium.daemon.assembly import load_projector_annotation

    assert load_projector_annotation(_config_with_calibration_file(tmp_path / "none.npz")) is None
    hub = Hub()
    sub = hub.bus.subscribe([TouchEvent])
    service, _ = _service([_frame(0.1 * i) for i in range(1, 4)], hub, annotation=None)
    await service.run()
    events = sub.drain()
    assert len(events) == 2 and all(e.extra == {} for e in events)
    assert service.health()["projector_annotation"] is None


def test_a_saved_calibration_is_loaded_and_an_unusable_one_ignored(tmp_path, caplog):
    from feelium.daemon.assembly import load_projector_annotation

    path = _calibration().save(tmp_path / "projector_calibration.npz")
    annotation = load_projector_annotation(_config_with_calibration_file(path))
    assert annotation is not None and annotation.calibration.camera_size == (32, 24)
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"not a calibration")
    assert load_projector_annotation(_config_with_calibration_file(broken)) is None
    assert "unusable" in caplog.text and "broken.npz" in caplog.text


def test_an_event_the_annotation_cannot_handle_is_published_unannotated():
    from feelium.skin.annotation import ProjectorAnnotation

    class Exploding:
        def region_at(self, u, v):
            raise RuntimeError("bad regions")

    annotation = ProjectorAnnotation(_calibration(), Exploding())
    event = _event(0.1, "down")
    assert annotation(event, (32, 24)) is event
    assert annotation.errors == 1 and "bad regions" in annotation.last_error


class LightRecordingPipeline(FakePipeline):
    """Records the projected light and spread the service hands over with each frame."""

    def process(self, t, frame, projected_light=None, projected_spread=None):
        self.lights = getattr(self, "lights", []) + [(projected_light, projected_spread)]
        return super().process(t, frame)


async def _run_over_two_canvases(factory, projected, first, second) -> TouchService:
    """Three 16x12 camera frames (0.1-0.3 s) through ``factory``'s pipeline with ``projected`` predicting the light;
    the projector's canvas is ``first`` (time, grey level), then ``second`` once the first has been followed."""
    hub = Hub()
    hub.projector_canvas.publish(first[0], np.full((4, 4), first[1], np.uint8))
    camera = ScriptedCamera([_frame(0.1 * i, size=(16, 12)) for i in range(1, 4)], delay=0.02)
    service = TouchService(
        CameraSource("scripted", lambda: camera), hub, TouchConfig(),
        pipeline_factory=factory, overlay=_overlay, projected=projected,
    )

    async def second_canvas():
        while service.health().get("projector_frames", 0) < 1:  # the first one followed, however busy the machine
            await asyncio.sleep(0.001)
        hub.projector_canvas.publish(second[0], np.full((4, 4), second[1], np.uint8))

    await asyncio.gather(service.run(), second_canvas())
    return service


async def test_the_projected_light_of_each_exposure_goes_with_its_frame_at_the_frame_size():
    """Projector frames shown at 0.0 (light 0.5) and 0.2 s (light 1.0); 33 ms latency, 30 ms exposure."""
    sizes = []

    def projected(size, box):
        sizes.append((size, box))
        return lambda canvas, out=None: np.full((size[1], size[0]), float(canvas[0, 0]) / 100.0, np.float32)

    service = await _run_over_two_canvases(LightRecordingPipeline, projected, (0.0, 50), (0.2, 100))
    (pipeline,) = FakePipeline.created
    assert sizes == [((16, 12), pipeline.roi)]  # the light is wanted only over the ROI the pipeline cuts
    assert all(light.shape == (12, 16) and spread.shape == (12, 16) for light, spread in pipeline.lights)
    levels = [round(float(light[0, 0]), 3) for light, _ in pipeline.lights]
    assert levels[-1] == 1.0  # at 0.3 s the exposure (0.252..0.282 on the projector's clock) saw the second frame
    assert float(pipeline.lights[-1][1].max()) == 0.0  # and no latency error could change that
    health = service.health()
    assert health["projection_compensation"] is True and health["projector_frames"] == 2


def test_projection_compensation_only_for_frames_that_contain_the_projectors_light(tmp_path):
    from feelium.daemon.assembly import load_projected_light

    path = _calibration(projector_size=(1280, 720)).save(tmp_path / "projector_calibration.npz")
    config = _config_with_calibration_file(path)
    assert (config.projector.width, config.projector.height) == (1280, 720)
    assert load_projected_light(config, "sim") is None  # auto: simulated frames hold no projection
    assert load_projected_light(config, "replay") is None
    factory = load_projected_light(config, "picamera2")
    assert factory is not None
    predict = factory((32, 24))
    predicted = predict(np.full((384, 512), 30, np.uint8))  # a dark grey skin canvas
    assert predicted.shape == (24, 32) and np.all(np.isfinite(predicted))
    assert float(np.median(predicted[8:16, 8:24])) < 0.9  # a dark projection dims the covered patch
    off = dataclasses.replace(config, rear_camera=dataclasses.replace(config.rear_camera, projection_compensation="off"))
    assert load_projected_light(off, "picamera2") is None
    on = dataclasses.replace(config, rear_camera=dataclasses.replace(config.rear_camera, projection_compensation="on"))
    assert load_projected_light(on, "sim") is not None
    missing = _config_with_calibration_file(tmp_path / "none.npz")
    assert load_projected_light(missing, "picamera2") is None


def test_the_daemon_takes_the_projectors_latency_measured_with_its_calibration(tmp_path):
    """A calibration that measured the projector's latency (``calibrate projector`` from a recording) sets touch's
    latency in the daemon, its spread widened, never narrowed; one that did not, or no file, leaves ``[touch]``."""
    from feelium.daemon.assembly import touch_config_with_measured_latency

    measured = dataclasses.replace(_calibration(projector_size=(1280, 720)), latency_s=0.081, latency_sigma_s=0.002)
    config = _config_with_calibration_file(measured.save(tmp_path / "measured.npz"))
    touch = touch_config_with_measured_latency(config)
    assert touch.projector_latency_s == 0.081 != config.touch.projector_latency_s
    assert touch.projector_latency_sigma_s == config.touch.projector_latency_sigma_s  # 2 ms narrows nothing
    unmeasured = _config_with_calibration_file(_calibration(projector_size=(1280, 720)).save(tmp_path / "plain.npz"))
    assert touch_config_with_measured_latency(unmeasured) is unmeasured.touch
    missing = _config_with_calibration_file(tmp_path / "none.npz")
    assert touch_config_with_measured_latency(missing) is missing.touch


async def test_a_failing_light_prediction_costs_only_the_compensation():
    def projected(size, box):
        def predict(frame, out=None):
            raise ValueError("canvas must be 512x384 grey uint8")

        return predict

    hub = Hub()
    hub.projector_canvas.publish(0.0, np.zeros((48, 64), np.uint8))
    sub = hub.bus.subscribe([TouchEvent])
    camera = ScriptedCamera([_frame(0.1 * i) for i in range(1, 4)], delay=0.02)
    service = TouchService(
        CameraSource("scripted", lambda: camera), hub, TouchConfig(),
        pipeline_factory=LightRecordingPipeline, overlay=_overlay, projected=projected,
    )
    await service.run()
    (pipeline,) = FakePipeline.created
    assert pipeline.lights == [(None, None)] * 3 and [e.phase for e in sub.drain()] == ["down", "up"]
    health = service.health()
    assert health["projected_errors"] == 3 and "512x384" in health["last_projected_error"]


class CoarsePipeline(FakePipeline):
    """Detects on a half-size grid (``light_grids``) and asks for the working resolution's light in a window."""

    light_grids = LightGrids(((8, 6), (1, 1, 6, 4)), ((16, 12), (2, 2, 12, 8)), 2)

    def process(self, t, frame, projected_light=None, projected_spread=None, fine_light=None):
        window = None if fine_light is None else fine_light(slice(1, 3), slice(4, 7))
        self.lights = getattr(self, "lights", []) + [(projected_light, window)]
        return super().process(t, frame)


async def test_a_coarse_pipeline_gets_its_light_on_its_grid_and_the_fine_light_by_windows():
    """The working grid's predictor is asked for first and handed to the detection grid's (they share the canvas's
    light); each frame's light comes at the detection size and the fine pass's window from the working grid's
    ``window``; a window that fails costs only that window (None: the pipeline upsamples)."""
    calls = []

    class Predictor:
        def __init__(self, size, box, *rest):
            calls.append((size, box, *rest))
            self.box = box

        def __call__(self, canvas, out=None):
            return np.full((self.box[3], self.box[2]), float(canvas[0, 0]) / 100.0, np.float32)

        def window(self, canvas, rows, cols):
            if canvas[0, 0] == 13:
                raise ValueError("no window")
            return np.full((rows.stop - rows.start, cols.stop - cols.start), float(canvas[0, 0]) / 10.0, np.float32)

    service = await _run_over_two_canvases(CoarsePipeline, Predictor, (0.0, 5), (0.15, 13))
    fine, coarse = calls
    assert fine == ((16, 12), (2, 2, 12, 8)) and coarse[:3] == ((8, 6), (1, 1, 6, 4), 2)
    assert isinstance(coarse[3], Predictor) and coarse[3].box == (2, 2, 12, 8)
    (pipeline,) = FakePipeline.created
    first_light, first_window = pipeline.lights[0]
    assert first_light.shape == (4, 6) and first_window.shape == (2, 3) and float(first_window[0, 0]) == 0.5
    assert pipeline.lights[-1][1] is None  # the last exposure saw the canvas whose window fails
    assert service.health()["projected_errors"] >= 1
