"""The thermal service end to end: simulated sensor seeing a scene -> presence events on the hub."""

import asyncio
import threading
import time

import numpy as np
import pytest

from feelium.daemon.config import parse_config
from feelium.events import PresenceEvent
from feelium.hub import Hub
from feelium.service import Service
from feelium.sim.thermal import ThermalSceneRenderer, WarmBody
from feelium.thermal import registers as reg
from feelium.thermal.config import ThermalConfig
from feelium.thermal.driver import Mlx90640Driver
from feelium.thermal.sim_device import Faults, SimMlx90640
from feelium.daemon.assembly import build_thermal
from feelium.thermal.service import ThermalService, sim_driver
from feelium.thermal.transport import SMBus2Transport


class FakeClock:
    """Hub time that advances a fixed step per read, so the test never waits on the wall clock."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 0.01
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += dt


def make_service(scene, faults=None, config=None, eeprom=None):
    clock = FakeClock()
    hub = Hub(clock=clock)
    cfg = config or ThermalConfig(refresh_hz=16.0, retry_backoff_s=0.01)
    sensors = []

    def make_driver():
        sensor = SimMlx90640(scene, clock=clock, sleep=clock.sleep, rng=np.random.default_rng(1), faults=faults, eeprom=eeprom)
        sensors.append(sensor)
        return Mlx90640Driver(SMBus2Transport(sensor.bus(), max_read_words=cfg.max_read_words), reg.ControlSettings(16.0, 18, "chess"))

    def sleep(dt):  # on the thermal thread: virtual time, and the GIL to the loop
        clock.sleep(dt)
        time.sleep(0)

    return hub, clock, ThermalService(cfg, hub, make_driver, "sim", sleep=sleep), sensors


async def run_until(service, clock, t_end):
    task = asyncio.create_task(service.run())
    while clock.t < t_end and not task.done():
        await asyncio.sleep(0)
    assert not task.done(), task.exception()
    await service.stop()
    task.cancel()
    try:
        await task
    except asyncio.CancelledError:
        pass


def test_build_thermal_honours_backend():
    hub = Hub()
    assert build_thermal(parse_config('[thermal]\nbackend = "off"\n'), hub) is None
    service = build_thermal(parse_config('[thermal]\nbackend = "sim"\n'), hub)
    assert isinstance(service, Service) and service.name == "thermal"


def test_bad_refresh_rate_is_a_config_error():
    with pytest.raises(Exception, match="refresh_hz"):
        parse_config("[thermal]\nrefresh_hz = 3.0\n")


@pytest.mark.slow
async def test_presence_events_reach_the_bus_and_state():
    renderer = ThermalSceneRenderer(np.random.default_rng(4), 22.0)
    scene = lambda t: renderer.frame(t, [WarmBody(0.25, 0.5, 0.0, 0.15)] if 3.0 < t < 6.0 else [])
    hub, clock, service, _ = make_service(scene)
    sub = hub.bus.subscribe([PresenceEvent])
    await run_until(service, clock, 10.0)
    events = sub.drain()
    phases = [e.phase for e in events if e.phase != "update"]
    assert phases == ["approach", "leave"], service.health()
    approach = next(e for e in events if e.phase == "approach")
    assert 3.0 < approach.t < 4.0 and approach.azimuth_deg < -10
    assert hub.state.snapshot()["presence"]["present"] is False
    health = service.health()
    assert health["frames"] > 50 and health["driver"]["io_errors"] == 0 and health["rejected"] == {}


async def test_i2c_errors_are_counted_never_fatal():
    renderer = ThermalSceneRenderer(np.random.default_rng(4), 22.0)
    scene = lambda t: renderer.frame(t, [])
    hub, clock, service, sensors = make_service(scene, faults=Faults(nack_rate=0.3, invalid_word_rate=0.2))
    await run_until(service, clock, 10.0)
    health = service.health()
    assert health["failures"] > 0 and "OSError" in health["last_error"]
    assert health["driver"]["retries"] > 0 and health["driver"]["io_errors"] > health["failures"]  # most NACKs retried away
    assert health["rejected"].get("invalid_word", 0) > 0
    assert health["frames"] > 10


async def test_bad_eeprom_is_reported_and_retried():
    hub, clock, service, sensors = make_service(np.full((24, 32), 22.0), eeprom=np.zeros(832, dtype=np.uint16))
    await run_until(service, clock, 0.5)
    health = service.health()
    assert health["frames"] == 0 and "all zero" in health["last_error"] and health["failures"] >= 2


@pytest.mark.parametrize("seed", [1, 2, 3])
async def test_between_sub_pages_it_sleeps_yet_reads_every_one_even_when_the_loop_wakes_it_late(seed):
    """Time passes only in the service's sleeps, each overslept by up to 40 ms (a loaded machine): at 8 Hz every
    sub-page the device writes is still read, no later than when polling all the time, with about two polls
    each instead of four or five."""
    from feelium.thermal.sim_device import VirtualClock

    clock = VirtualClock()
    rng = np.random.default_rng(seed)
    hub = Hub(clock=clock)
    cfg = ThermalConfig(refresh_hz=8.0)
    renderer = ThermalSceneRenderer(np.random.default_rng(4), 22.0)
    sensor = SimMlx90640(lambda t: renderer.frame(t, []), clock=clock, sleep=clock.sleep, rng=np.random.default_rng(1))

    def make_driver():
        return Mlx90640Driver(SMBus2Transport(sensor.bus(), max_read_words=cfg.max_read_words), reg.ControlSettings(8.0, 18, "chess"))

    def late_sleep(dt):
        clock.sleep(dt + (float(rng.uniform(0.0, 0.04)) if rng.random() < 0.3 else 0.0))
        time.sleep(0)

    service = ThermalService(cfg, hub, make_driver, "sim", sleep=late_sleep)
    waits = []  # how long each sub-page had been ready when it was read (reads take no virtual time here)
    detect = service._detect

    def timed_detect(t, image):
        waits.append(t - (sensor._t0 + sensor._measured * sensor.period_s))
        return detect(t, image)

    service._detect = timed_detect
    await run_until(service, clock, 20.0)
    counters = service.driver.counters
    polls = counters.subpages + counters.not_ready + counters.torn + counters.stale
    assert counters.torn == 0 and counters.stale == 0
    assert counters.subpages >= sensor.subpages_written - 1  # the one being written when the test stopped
    assert polls <= 2.5 * counters.subpages
    assert max(waits) <= 0.25 / 8.0 + 0.04 + 1e-9  # a poll period and the worst oversleep, as when polling all the time


def _service_recording_buses() -> tuple[ThermalService, list]:
    """A simulated thermal service at 16 Hz whose drivers' buses are kept, to see which are open."""
    hub = Hub()
    cfg = ThermalConfig(refresh_hz=16.0)
    buses = []

    def make_driver():
        driver = sim_driver(cfg, hub, seed=1)
        buses.append(driver.transport.bus)
        return driver

    return ThermalService(cfg, hub, make_driver, "sim"), buses


async def test_the_thermal_thread_publishes_through_the_loop_and_a_stop_ends_it_closing_the_bus():
    """Real time, the default waits: frames reach the hub's state from the thermal thread's batches; after a stop
    the run returns, the thread closes the bus and reads no more."""
    service, buses = _service_recording_buses()
    task = asyncio.create_task(service.run())
    loop = asyncio.get_running_loop()
    deadline = loop.time() + 20.0
    while service.frames < 2 and loop.time() < deadline and not task.done():
        await asyncio.sleep(0.02)
    assert service.frames >= 2, service.health()
    assert service.hub.state.snapshot()["presence"]["present"] is False  # published on the loop from the thread's batch
    await service.stop()
    await asyncio.wait_for(task, 5.0)
    assert len(buses) == 1 and buses[0].closed
    frames = service.frames
    await asyncio.sleep(0.3)
    assert service.frames == frames


async def test_a_stop_interrupts_the_thermal_threads_wait():
    """A sensor that fails waits out a backoff on the thread (here 60 s); a stop ends that wait, not the backoff."""
    hub = Hub()
    cfg = ThermalConfig(refresh_hz=16.0, retry_backoff_s=60.0)

    def make_driver():
        sensor = SimMlx90640(np.full((24, 32), 22.0), clock=hub.clock, sleep=time.sleep, rng=np.random.default_rng(1),
                             eeprom=np.zeros(832, dtype=np.uint16))
        return Mlx90640Driver(SMBus2Transport(sensor.bus(), max_read_words=cfg.max_read_words), reg.ControlSettings(16.0, 18, "chess"))

    service = ThermalService(cfg, hub, make_driver, "sim")
    task = asyncio.create_task(service.run())
    loop = asyncio.get_running_loop()
    deadline = loop.time() + 20.0
    while not service.failures and loop.time() < deadline:
        await asyncio.sleep(0.02)
    assert service.failures == 1 and "all zero" in service.last_error
    await service.stop()
    await asyncio.wait_for(task, 10.0)  # far inside the 60 s backoff
    assert service.failures == 1


async def test_a_sensor_that_goes_silent_after_frames_does_not_read_ok():
    """A part whose reads stop bringing frames (the new-data bit never set again, or a read stuck on the thread)
    raises nothing, so no failure is counted: health must still say frames stopped, not ok (session 22 review)."""
    renderer = ThermalSceneRenderer(np.random.default_rng(4), 22.0)
    hub, clock, service, _ = make_service(lambda t: renderer.frame(t, []))
    task = asyncio.create_task(service.run())
    while service.frames < 3 and clock.t < 10.0 and not task.done():
        await asyncio.sleep(0)
    assert service.frames >= 3 and service.health()["condition"] == "ok"
    service.driver.poll = lambda: None  # silent from now on: every poll finds nothing ready
    frames, started = service.frames, clock.t
    while clock.t < started + 5.0 and not task.done():
        await asyncio.sleep(0)
    await service.stop()
    await asyncio.wait_for(task, 5.0)
    assert service.frames <= frames + 1  # at most the one being assembled
    health = service.health()
    assert health["condition"] == "degraded" and "no thermal frame" in health["reason"], health


async def test_a_cancelled_run_started_again_reads_on_with_one_thread_and_an_open_bus():
    """``run`` cancelled (not stopped) and called again, as ``feelium.service`` allows: the old thread must end
    without closing the bus under the new one's reads, and only one thread may read the sensor."""
    import threading

    service, buses = _service_recording_buses()
    loop = asyncio.get_running_loop()

    async def frames_after(count):
        task = asyncio.create_task(service.run())
        deadline = loop.time() + 20.0
        while service.frames < count and loop.time() < deadline and not task.done():
            await asyncio.sleep(0.02)
        return task

    first = await frames_after(2)
    first.cancel()
    with pytest.raises(asyncio.CancelledError):
        await first
    second = await frames_after(service.frames + 4)
    assert not second.done() and service.failures == 0, service.health()
    assert [t.name.startswith("thermal") for t in threading.enumerate()].count(True) == 1
    assert not any(bus.closed for bus in buses[-1:]), "the bus in use was closed under the new thread"
    await service.stop()
    await asyncio.wait_for(second, 5.0)
    assert all(bus.closed for bus in buses)


def test_health_reads_the_driver_once_while_the_thread_may_drop_it():
    """The thermal thread sets ``driver`` to None after a bad calibration; a ``health()`` on the loop between its
    check and its use must not raise (that reads as 'health() failed' in the report). The property below is that
    interleaving: the thread drops the driver right after the check (session 22 review)."""
    renderer = ThermalSceneRenderer(np.random.default_rng(4), 22.0)
    hub, clock, service, sensors = make_service(lambda t: renderer.frame(t, []))
    service._start_driver()
    driver = service.__dict__.pop("driver")
    reads = iter([driver])

    class Racing(ThermalService):
        driver = property(lambda self: next(reads, None), lambda self, value: None)

    service.__class__ = Racing
    health = service.health()
    assert health["driver"]["io_errors"] == 0
