"""``feelium bench board``: the real daemon on its real data path at real rates, projected onto a Pi Zero 2 W.

What runs, and what does not count:

- the daemon's own services as ``feelium run`` assembles them, on the sim
  backends where hardware would be (thermal's I2C-level device, the audio
  devices, the projector's display), with two exceptions that keep the
  simulator's own cost out of the figures: both cameras play frames rendered
  once before the run (:mod:`feelium.lab.daemon.preloaded`), and the motor
  board runs in another process behind ``socket://`` (:mod:`feelium.lab.daemon.board_server`);
- three headset clients in a third process (:mod:`feelium.lab.daemon.headset`).

Per service it reports the rate against its target, deadline misses and CPU
milliseconds per second of thread CPU time (:mod:`feelium.lab.daemon.attribution`),
then the process total, the event loop's lag, resident memory, and the
projection onto the board (:mod:`feelium.lab.daemon.projection`).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Coroutine, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, NamedTuple, TypeVar

import cv2
import numpy as np

from feelium.audio.backends import SimMicrophone
from feelium.daemon.assembly import SERVICES, build_projector, load_projected_light, load_projector_annotation
from feelium.daemon.config import Config, load_config
from feelium.daemon.eventloop import loop_kind, new_event_loop
from feelium.daemon.memory import tune_malloc
from feelium.daemon.runner import WORKER_THREADS, background_nice_here, run_daemon, with_overrides
from feelium.daemon.sdnotify import Notifier
from feelium.flight.lateness import counts_between, percentile_ms
from feelium.hub import Hub
from feelium.priority import background_nice, set_background_nice
from feelium.lab.daemon.attribution import (
    ChargingExecutor,
    Ledger,
    callback_overhead_s,
    charge,
    charge_loop_callbacks,
    charged_apart,
    thread_cpu,
)
from feelium.lab.daemon.bench import peak_rss_mb, resident_mb, restart_peak_rss
from feelium.lab.daemon.host import host_reference
from feelium.lab.daemon.numeric import NumericProfiler, numeric_shares
from feelium.lab.daemon.perfsplit import PerfSampler, perf_usable, pooled_shares
from feelium.lab.daemon.preloaded import PreloadedSource, encoded_once, front_frames, rear_frames
from feelium.lab.daemon.projection import project
from feelium.lab.daemon.quota import join
from feelium.lab.daemon.samples import SampleBlock
from feelium.lab.report import emit_report
from feelium.skin.projector_map import load_or_default
from feelium.thermal.sim_device import SimMlx90640
from feelium.service import Service

TOKEN = "bench-board-token"
T = TypeVar("T")
WARMUP_S = 3.0  # devices open, caches warm, the headset clients connect
FIRST_TOUCH_FRAME_S = 30.0  # the longest the window waits for the touch pipeline's first frame
# The lag probe is the bench's own sleeper, not the daemon's: each wake-up costs the loop's thread what any timer
# does. At 10 ms it cost that thread ~5 ms/s (2 interleaved pairs, 1 min, session 20: 51.2 / 52.3 against 47.3 /
# 46.2 ms/s at 50 ms), 0.05 of a projected Pi core charged to the daemon. How late a sleeper wakes does not
# depend on its period; 20 samples a second still give 1 200 a minute for the p99. Resident memory is read on the
# same wake-ups, every RSS_EVERY_S (:class:`LoopProbe`), not by timers of its own.
LAG_PROBE_S = 0.05
RSS_EVERY_S = 0.5
REAR_LOOP_S = 6.0  # seconds of rear frames preloaded (touches every ~1.5 s); longer only costs memory
FRONT_LOOP_S = 1.0
# The projector writes into a framebuffer laid out as the blimp's: the Pi's KMS framebuffer (vc4's fbdev
# emulation) is 16 bits per pixel unless configured otherwise (Linux commit "drm/vc4: Use 16bpp by default for
# the fbdev buffer", 2019). Until session 20 the bench's display was the sim one, which writes nothing.
FRAMEBUFFER_BPP = 16


class Framebuffer(NamedTuple):
    device: str
    sysfs_root: str
# A simulated device's own work inside a service's call, charged apart (:func:`sim_devices_apart`): the device's
# class, its method, the service that calls it.
SIM_DEVICE_CALLS: tuple[tuple[type, str, str], ...] = (
    (SimMlx90640, "transaction", "thermal"),
    (SimMicrophone, "_synth", "audio"),
)


@dataclasses.dataclass
class Cameras:
    """Both preloaded cameras, kept for their late counts and the bytes to take out of resident memory."""

    rear: PreloadedSource
    front: PreloadedSource

    @property
    def nbytes(self) -> int:
        return self.rear.nbytes + self.front.nbytes


def prepare(config: Config, front_fps: float) -> Cameras:
    """Render both cameras' frames once, before anything is measured, in a thread that ends when they are done.

    The simulator's front camera stamps its frames with ``cv2.putText``, and OpenCV 5 keeps a ~5.7 MB font
    cache in each thread that draws text until the thread ends: rendered on the main thread, it stayed in the
    resident memory measured for the daemon, which never renders a simulated frame on the blimp."""

    def render() -> Cameras:
        size = (config.touch.width, config.touch.height)
        rear, roi = rear_frames(config.sim, size, config.rear_camera.fps, REAR_LOOP_S)
        front = front_frames((config.front_camera.width, config.front_camera.height), front_fps, FRONT_LOOP_S, config.sim.seed)
        if front_jpeg_by(config) == "camera":
            front = encoded_once(front, config.http.jpeg_quality)
        return Cameras(PreloadedSource(rear, config.rear_camera.fps, roi), PreloadedSource(front, front_fps))

    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="bench-prepare") as passing:
        return passing.submit(render).result()


def front_jpeg_by(config: Config) -> str:
    """Who makes the headset's JPEGs on the blimp this config describes: ``camera`` (the picamera2 front camera's
    hardware encoder on a Pi Zero 2 W, or a USB camera's own MJPEG; ``[front_camera] jpeg`` auto or hardware) or
    ``daemon`` (software)."""
    return "daemon" if config.front_camera.jpeg == "software" else "camera"


def fake_framebuffer(directory: Path, size: tuple[int, int], bpp: int = FRAMEBUFFER_BPP) -> Framebuffer:
    """A file the size of a ``size`` framebuffer at ``bpp`` and the sysfs entries that describe it, in ``directory``
    (memory-backed where /dev/shm exists, as a framebuffer is: the kernel writes nothing back to a disk)."""
    sysfs = directory / "sys"
    (sysfs / "fb0").mkdir(parents=True)
    (sysfs / "fb0" / "virtual_size").write_text(f"{size[0]},{size[1]}\n")
    (sysfs / "fb0" / "bits_per_pixel").write_text(f"{bpp}\n")
    device = directory / "fb0"
    with open(device, "wb") as fb:
        fb.truncate(size[0] * size[1] * bpp // 8)
    return Framebuffer(str(device), str(sysfs))


def builders(cameras: Cameras, framebuffer: Framebuffer) -> tuple[tuple[str, Any], ...]:
    """The daemon's assembly with both cameras on the preloaded frames and the projector writing into
    ``framebuffer`` (a file laid out as the Pi's, so the writes cost what they cost on the blimp);
    every other part as ``feelium run`` builds it."""

    def touch(config: Config, hub: Hub) -> Service:
        from feelium.touch.service import TouchService

        source = cameras.rear.source()
        return TouchService(
            source, hub, config.touch,
            debug_video_fps=config.rear_camera.debug_video_fps, annotation=load_projector_annotation(config),
            projected=load_projected_light(config, source.backend),
        )

    def front_camera(config: Config, hub: Hub) -> Service:
        from feelium.front_camera.service import FrontCameraService

        return FrontCameraService(cameras.front.source(), hub)

    def projector(config: Config, hub: Hub) -> Service | None:
        from feelium.projector.display import FbdevDisplay

        return build_projector(config, hub, FbdevDisplay(framebuffer.device, framebuffer.sysfs_root))

    replaced = {"touch": touch, "front_camera": front_camera, "projector": projector}
    return tuple((name, replaced.get(name, build)) for name, build in SERVICES)


def bench_config(config: Config, rear_fps: float, board_port: str, calibration: Path | None = None) -> Config:
    """Sim backends, the rear camera at ``rear_fps``, flight over the board process's pty, HTTP on a free port;
    with ``calibration`` (a projector calibration file), the projector and touch use it as on the blimp: touch
    events annotated with the skin, and the projected light compensated in every rear frame."""
    config = with_overrides(config, sim=True)
    rear = dataclasses.replace(config.rear_camera, fps=rear_fps)
    if calibration is not None:
        rear = dataclasses.replace(rear, projection_compensation="on")
        projector = dataclasses.replace(
            config.projector, calibration=dataclasses.replace(config.projector.calibration, file=str(calibration))
        )
        config = dataclasses.replace(config, projector=projector)
    return dataclasses.replace(
        config,
        rear_camera=rear,
        flight=dataclasses.replace(config.flight, backend="serial", port=board_port),
        http=dataclasses.replace(config.http, port=0, token=TOKEN, host="127.0.0.1"),
    )


def _percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values, dtype=np.float64), q)) if values else float("nan")


@contextlib.contextmanager
def sim_devices_apart(ledger: Ledger) -> Iterator[None]:
    """While open, every call of :data:`SIM_DEVICE_CALLS` is charged to ``SIM_DEVICES`` instead of its service."""
    with contextlib.ExitStack() as stack:
        for owner, method, service in SIM_DEVICE_CALLS:
            stack.enter_context(charged_apart(owner, method, service, ledger))
        yield


class LoopProbe:
    """The bench's one sleeper on the daemon's loop: how late the loop wakes it (what any callback waits behind the
    others) while :attr:`window` is set and, every :data:`RSS_EVERY_S`, resident memory: the peak from start-up
    until the daemon is told to stop, the samples while :attr:`window` is set. Lags outside the window (start-up,
    the headset's report, the daemon's shutdown) are not the steady state the percentiles describe.

    One timer for both: until session 22 the window and the peak read memory on timers of their own, two more
    wake-ups of the loop every ``RSS_EVERY_S`` charged to the daemon, each reading ``/proc/self/status``."""

    def __init__(self, seconds: float) -> None:
        # Fixed blocks, written before the run: the bench's own samples must not show as the daemon's memory growth.
        self.lags_ms = SampleBlock(math.ceil(seconds / LAG_PROBE_S) + 1)  # it sleeps at least LAG_PROBE_S a sample
        self.rss_mb = SampleBlock(math.ceil(seconds / RSS_EVERY_S) + 2)
        self.peak_mb = 0.0  # start-up included, not in the window's samples
        self.window = False

    def open_window(self) -> None:
        """Samples from now on are the measured window's."""
        self.window = True

    async def run(self, daemon_stop: asyncio.Event, stop: asyncio.Event) -> None:
        """Sample until ``stop``; memory only until ``daemon_stop`` (the daemon's shutdown is not its steady state)."""
        next_rss = time.perf_counter()
        while not stop.is_set():
            due = time.perf_counter() + LAG_PROBE_S
            await asyncio.sleep(LAG_PROBE_S)
            now = time.perf_counter()
            if self.window:
                self.lags_ms.add(1000.0 * max(0.0, now - due))
            if now >= next_rss and not daemon_stop.is_set():
                next_rss = now + RSS_EVERY_S
                mb = resident_mb()
                self.peak_mb = max(self.peak_mb, mb)
                if self.window:
                    self.rss_mb.add(mb)


def _start_headset(port: int, seconds: float, motion_transport: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "feelium.lab.daemon.headset", f"http://127.0.0.1:{port}/api/v1", TOKEN, str(seconds), motion_transport],
        stdout=subprocess.PIPE, text=True,
    )


async def _measure(
    config: Config,
    cameras: Cameras,
    framebuffer: Framebuffer,
    seconds: float,
    warmup_s: float,
    cgroup: Path | None,
    motion_transport: str = "websocket",
    profiler: NumericProfiler | PerfSampler | None = None,
) -> dict[str, Any]:
    """Run the daemon; measure over ``seconds`` after the warm-up while the headset process drives it.

    ``profiler``: installed before any service thread starts, counting over the same window (a hook slows the
    profiled threads, a sampler the whole process a little: such a run gives shares, not figures)."""
    if profiler is not None:
        profiler.install()
    ledger = Ledger()
    loop = asyncio.get_running_loop()
    ledger.per_callback = loop_kind(loop) == "asyncio"  # uvloop runs its callbacks in C: charge_loop_callbacks sees none
    loop.set_default_executor(ChargingExecutor(ledger, WORKER_THREADS))
    undo = charge_loop_callbacks(ledger)
    overhead_s = callback_overhead_s(loop, ledger)
    hub, stop, probe_stop = Hub(), asyncio.Event(), asyncio.Event()
    probe = LoopProbe(seconds)
    out: dict[str, Any] = {}
    kernel_peak = restart_peak_rss()  # from the daemon's start: the preloaded frames in it, as in every sample
    started = asyncio.Event()

    async def window() -> None:
        await started.wait()
        while not isinstance(port := hub.health()["services"]["http"].get("port"), int):
            await asyncio.sleep(0.05)  # bound once the http service has started
        # The touch pipeline is built at its first frame, in its own thread (seconds on a loaded machine, with the
        # projected-light predictor): start-up, not steady state, so the warm-up starts after it (bounded).
        deadline = time.monotonic() + FIRST_TOUCH_FRAME_S
        while not hub.health()["services"].get("touch", {}).get("frames") and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        headset = _start_headset(port, seconds + warmup_s, motion_transport)
        try:
            if cgroup is not None:
                out["cpu_quota"] = {"cgroup": str(cgroup), "quota_period_us": join(cgroup)}  # after the children started
            await asyncio.sleep(warmup_s)
            first, threads_before, cpu_before = hub.health(), thread_cpu(), os.times()
            probe.open_window()
            ledger.counting = True
            if profiler is not None:
                profiler.counting = True
            start = time.monotonic()
            while (elapsed := time.monotonic() - start) < seconds:
                await asyncio.sleep(seconds - elapsed)
            probe.window = False
            out["rss_hwm"] = peak_rss_mb() if kernel_peak else None  # start-up and window, before the shutdown
            ledger.counting = False
            if profiler is not None:
                profiler.counting = False
            cpu_after, threads_after = os.times(), thread_cpu()
            out.update(
                wall=time.monotonic() - start, first=first, last=hub.health(),
                cpu_s=(cpu_after.user + cpu_after.system) - (cpu_before.user + cpu_before.system),
                charged=charge(threads_before, threads_after, ledger),
                callbacks=ledger.callbacks,
                callbacks_by=dict(ledger.callbacks_by),
                callback_overhead_s=overhead_s,
                event_loop=loop_kind(loop),
                loop_thread_s=threads_after.get("MainThread", 0.0) - threads_before.get("MainThread", 0.0),
                headset=json.loads((await asyncio.to_thread(headset.communicate, None, 30.0))[0].strip().splitlines()[-1]),
            )
        finally:
            if headset.poll() is None:
                headset.kill()
            stop.set()  # a failed measurement stops the daemon too; its error surfaces below

    tasks = [asyncio.create_task(window()), asyncio.create_task(probe.run(stop, probe_stop))]
    # Simulated devices' own work, which the blimp's hardware does instead, moves out of the service that calls it
    # (not in a profiled run, whose shares are of each service with its device: their numeric seconds are not
    # split): the simulated MLX90640 writes its RAM inside each of thermal's I2C reads (the Pi pays an I2C
    # transfer), and the simulated microphone synthesises its tone on the loop thread (the Pi's ALSA capture
    # hands over samples the sound card recorded).
    apart = sim_devices_apart(ledger) if profiler is None else contextlib.nullcontext()
    try:
        with apart:
            await run_daemon(config, stop=stop, hub=hub, notifier=Notifier({}), builders=builders(cameras, framebuffer),
                             on_started=lambda h, s: started.set())
    finally:
        if not tasks[0].done():
            tasks[0].cancel()  # the daemon ended before the window did (it failed): stop measuring
        stop.set()
        probe_stop.set()
        undo()
        if profiler is not None:
            profiler.uninstall()
        done = await asyncio.gather(*tasks, return_exceptions=True)
    if isinstance(done[0], Exception):
        raise done[0]  # the measurement failed (e.g. the headset process): not a report with holes
    out["lags_ms"] = probe.lags_ms.values().tolist()
    out["rss"] = probe.rss_mb.values().tolist()
    out["rss_sampled_peak"] = max([probe.peak_mb, *out["rss"]])
    out["rss_peak"] = max(out["rss_sampled_peak"], out.get("rss_hwm") or 0.0)
    out["rss_peak_source"] = "kernel high-water mark (VmHWM)" if out.get("rss_hwm") else f"sampled every {RSS_EVERY_S} s"
    return out


def _delta(first: dict[str, Any], last: dict[str, Any], service: str, key: str) -> float:
    a, b = first["services"].get(service, {}).get(key), last["services"].get(service, {}).get(key)
    return float(b) - float(a) if isinstance(a, (int, float)) and isinstance(b, (int, float)) else 0.0


def _tick_lateness(first: dict[str, Any], last: dict[str, Any]) -> dict[str, float | str | None]:
    """The flight tick's lateness over the window (p50, p99 as bin upper bounds, ms): the poll's start on the serial
    thread and the controller's step on the loop, each against the tick's due time. Above the last bin it is
    the string ``">EDGE"`` (JSON has no infinity)."""
    out: dict[str, float | str | None] = {}
    for part in ("start", "step"):
        a = first["services"].get("flight", {}).get("tick_late_ms", {}).get(part)
        b = last["services"].get("flight", {}).get("tick_late_ms", {}).get(part)
        if a is None or b is None:
            continue
        window = counts_between(a["counts"], b["counts"])
        for q in (50, 99):
            value = percentile_ms(b["edges_ms"], window, q)
            out[f"tick_{part}_late_ms_p{q}"] = f">{b['edges_ms'][-1]}" if value == math.inf else value
    return out


def service_rows(measured: dict[str, Any], config: Config, cameras: Cameras, front_fps: float) -> dict[str, dict[str, Any]]:
    """Rate, target and misses per service over the window, and the CPU ms per second charged to it.

    A miss is a frame or cycle due that was not done in time: the touch service's dropped frames, the
    front camera's frames its reader fetched late, flight's overruns, late motion requests; where a
    service keeps no such count (thermal, audio capture, projector, MJPEG delivery) it is the shortfall
    of work done against the target.
    """
    first, last, wall = measured["first"], measured["last"], measured["wall"]
    headset = measured["headset"]

    def row(done: float, target: float, missed: float | None = None) -> dict[str, Any]:
        shortfall = max(0.0, 1.0 - done / (target * wall)) if target > 0 else 0.0
        miss = missed / max(done + missed, 1.0) if missed is not None else shortfall
        return {"rate_hz": round(done / wall, 2), "target_hz": target, "miss_pct": round(100.0 * miss, 2),
                "miss_kind": "counted" if missed is not None else "shortfall"}

    touch_frames = _delta(first, last, "touch", "frames")
    rows = {
        "touch": row(touch_frames, config.rear_camera.fps, _delta(first, last, "touch", "dropped_frames")),
        "front_camera": row(_delta(first, last, "front_camera", "frames"), front_fps),
        "thermal": row(_delta(first, last, "thermal", "frames"), config.thermal.refresh_hz),  # one per sub-page
        "audio": row(_delta(first, last, "audio", "captured_chunks"), 1000.0 / config.audio.chunk_ms),
        "projector": row(_delta(first, last, "projector", "frames"), config.projector.fps),
        "flight": row(_delta(first, last, "flight", "cycles"), config.flight.rate_hz, _delta(first, last, "flight", "overruns")),
        "http": row(headset["mjpeg"]["frames"] * wall / headset["seconds"], front_fps),
    }
    rows["front_camera"]["late_frames_total"] = cameras.front.late
    rows["flight"]["link_losses"] = int(_delta(first, last, "flight", "link_losses"))  # a starved board process shows here
    rows["flight"].update(_tick_lateness(first, last))
    # A wake-up is counted when the pipeline thread posts and a frame when the loop publishes it, so a batch in
    # flight at the last snapshot counts its wake-up without its frame: the counts are kept for that reading.
    touch_wakeups = _delta(first, last, "touch", "loop_wakeups")
    rows["touch"].update(loop_wakeups=int(touch_wakeups), frames=int(touch_frames),
                         loop_wakeups_per_frame=round(touch_wakeups / max(touch_frames, 1.0), 2))
    moves = headset["motion"]
    rows["headset_motion"] = {"transport": moves["transport"], "rate_hz": moves["rate_hz"], "target_hz": moves["target_hz"], "miss_kind": "counted",
                              "miss_pct": round(100.0 * moves["late"] / max(moves["sent"], 1), 2),
                              "rtt_ms_p50": moves["rtt_ms_p50"], "rtt_ms_p99": moves["rtt_ms_p99"]}
    for name, kinds in measured["charged"].items():
        entry = rows.setdefault(name, {"rate_hz": None, "target_hz": None, "miss_pct": None})
        entry["cpu_ms_per_s"] = round(1000.0 * sum(kinds.values()) / wall, 2)
        entry["cpu_ms_per_s_by_kind"] = {kind: round(1000.0 * s / wall, 2) for kind, s in sorted(kinds.items())}
    for entry in rows.values():
        entry.setdefault("cpu_ms_per_s", 0.0)
    return rows


def run_on_daemon_loop(config: Config, main: Coroutine[Any, Any, T]) -> T:
    """Run ``main`` on the event loop ``feelium run`` would choose (``[daemon] event_loop``), as the daemon runs."""
    with asyncio.Runner(loop_factory=lambda: new_event_loop(config.daemon.event_loop)[0]) as runner:
        return runner.run(main)


@contextlib.contextmanager
def _board_process() -> Iterator[str]:
    """The emulated motor board in a process of its own; yields its serial port (it serves one connection)."""
    board = subprocess.Popen([sys.executable, "-m", "feelium.lab.daemon.board_server"], stdout=subprocess.PIPE, text=True)
    try:
        yield board.stdout.readline().strip() if board.stdout else ""
    finally:
        board.kill()
        board.wait()


def bench_board(
    config: Config,
    minutes: float,
    *,
    front_fps: float | None = None,
    rear_fps: float = 30.0,
    warmup_s: float = WARMUP_S,
    cgroup: Path | None = None,
    motion_transport: str = "websocket",
    projected_light: bool = True,
    numeric_split_s: float = 0.0,
    numeric_split_by: str = "auto",
) -> dict[str, Any]:
    """Start the board process, run and measure the daemon for ``minutes``, project; every number in one dict.

    ``projected_light``: give the daemon a projector calibration (:func:`simulated_calibration`) so touch
    compensates the projected light in every rear frame as it does on the blimp (the preloaded frames hold no
    projector light, so this measures the cost, not the benefit).

    ``numeric_split_s``: then run the daemon again, this long, with the numeric profiler
    (:mod:`feelium.lab.daemon.numeric`), and project each service's parts by their measured numeric share;
    0 projects everything at 10x. ``numeric_split_by``: ``perf`` samples the process from outside
    (:mod:`feelium.lab.daemon.perfsplit`), ``hook`` times numpy's and OpenCV's calls inside it (a lower bound of
    the share), ``auto`` the first where ``perf`` is usable."""
    host = host_reference()  # before anything else runs in this process
    scratch = tempfile.TemporaryDirectory(prefix="feelium-bench-")
    memory = tempfile.TemporaryDirectory(prefix="feelium-bench-fb-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None)
    split: dict[str, Any] | None = None
    try:
        framebuffer = fake_framebuffer(Path(memory.name), (config.projector.width, config.projector.height))
        with _board_process() as port:
            calibration = simulated_calibration(config, Path(scratch.name)) if projected_light else None
            config = bench_config(config, rear_fps, port, calibration)
            front_fps = front_fps or config.front_camera.fps
            malloc = tune_malloc(config.daemon.malloc_arenas, config.daemon.malloc_mmap_threshold_kb)
            set_background_nice(background_nice_here(config.daemon.background_nice, on_pi=True))  # as `feelium run` does on the Pi
            cameras = prepare(config, front_fps)
            load_before = os.getloadavg()[0]
            measured = run_on_daemon_loop(config, _measure(config, cameras, framebuffer, 60.0 * minutes, warmup_s, cgroup, motion_transport))
            load_after = os.getloadavg()[0]
        # Again once the daemon has stopped: a VM's host can slow down between runs or during one (the same code
        # read 1.9 and 2.1 Pi cores on the same machine), and the two readings say whether it did.
        host_after = host_reference()
        if numeric_split_s > 0:
            method = numeric_split_by if numeric_split_by != "auto" else ("perf" if perf_usable() else "hook")
            with _board_process() as port:
                profiler: NumericProfiler | PerfSampler = NumericProfiler() if method == "hook" else PerfSampler(Path(scratch.name))
                profiled = dataclasses.replace(config, flight=dataclasses.replace(config.flight, port=port))
                run = run_on_daemon_loop(profiled, _measure(profiled, cameras, framebuffer, numeric_split_s, warmup_s, None, motion_transport, profiler))
                split = {"seconds": round(run["wall"], 2), "method": method}
                if isinstance(profiler, PerfSampler):
                    try:
                        shares, split["samples"] = profiler.shares()
                    except (OSError, subprocess.SubprocessError) as exc:  # the measured run stands; only its split is lost
                        print(f"feelium bench board: perf's samples unreadable ({exc}): everything projected at 10x", file=sys.stderr)
                        split = None
                    else:
                        split["shares"] = pooled_shares(shares, run["charged"])
                else:
                    split["shares"] = numeric_shares(profiler.seconds, run["charged"])
    finally:
        scratch.cleanup()
        memory.cleanup()
    wall = measured["wall"]
    preload_mb = cameras.nbytes / 2**20
    window = measured["rss"]
    rows = service_rows(measured, config, cameras, front_fps)
    result: dict[str, Any] = {
        "seconds": round(wall, 2),
        "cpus": os.cpu_count(),
        "host": host,
        "host_after": {key: host_after[key] for key in ("python_ms", "numeric_ms")},
        "load_average_1min_before_after": [round(load_before, 2), round(load_after, 2)],
        "malloc": malloc or "glibc defaults",
        "background_nice": background_nice(),
        "opencv_threads": cv2.getNumThreads(),  # [daemon] opencv_threads as the daemon applied it
        "rear": {"size": [config.touch.width, config.touch.height], "fps": config.rear_camera.fps},
        "front": {"size": [config.front_camera.width, config.front_camera.height], "fps": front_fps, "jpeg_by": front_jpeg_by(config)},
        "process_cpu_ms_per_s": round(1000.0 * measured["cpu_s"] / wall, 1),
        "loop_thread_ms_per_s": round(1000.0 * measured["loop_thread_s"] / wall, 1),
        "loop_callbacks_per_s": round(measured["callbacks"] / wall),
        "loop_callbacks_per_s_by_origin": {
            name: round(count / wall, 1) for name, count in sorted(measured["callbacks_by"].items(), key=lambda kv: -kv[1])
        },
        "bench_overhead_ms_per_s": round(1000.0 * measured["callbacks"] * measured["callback_overhead_s"] / wall, 1),
        "loop_lag_p50_ms": round(_percentile(measured["lags_ms"], 50), 2),
        "loop_lag_p99_ms": round(_percentile(measured["lags_ms"], 99), 2),
        "loop_lag_max_ms": round(max(measured["lags_ms"], default=float("nan")), 2),
        "preloaded_frames_mb": round(preload_mb, 1),
        "rss_mb": round(statistics.median(window[len(window) // 2 :]) - preload_mb, 1),
        "rss_peak_mb": round(measured["rss_peak"] - preload_mb, 1),
        "rss_peak_sampled_mb": round(measured["rss_sampled_peak"] - preload_mb, 1),
        "rss_peak_source": measured["rss_peak_source"],
        "rss_growth_mb": _growth_mb(window),
        "cpu_quota": measured.get("cpu_quota"),
        "projected_light_compensation": projected_light,
        "motion_transport": motion_transport,
        "event_loop": measured["event_loop"],
        "services": rows,
        "headset": measured["headset"],
    }
    result["numeric_split"] = split
    result.update(project(result, split["shares"] if split is not None else None))
    return result


def simulated_calibration(config: Config, directory: Path) -> Path:
    """The projector calibration the daemon would fall back to (the rear ROI mapped affinely onto the
    projector), written as a file: with a file, touch compensates the projected light and annotates events."""
    size = (config.projector.width, config.projector.height)
    roi = tuple(config.rear_camera.roi) if config.rear_camera.roi else None
    return load_or_default(directory / "missing.npz", size, roi).save(directory / "projector_calibration.npz")  # type: ignore[arg-type]


def _growth_mb(window: list[float]) -> float | None:
    """Resident memory growth after warm-up (a leak over a long run): the median of the run's last fifth
    minus that of its second fifth (the first fifth is warm-up: caches and pools filling)."""
    fifth = len(window) // 5
    if fifth < 1:
        return None  # too short a run to tell
    return round(statistics.median(window[-fifth:]) - statistics.median(window[fifth : 2 * fifth]), 1)


def _callbacks_line(result: dict[str, Any]) -> str:
    if result["event_loop"] != "asyncio":  # uvloop's callbacks run in C: the bench cannot time them one by one
        return (
            f"  on {result['event_loop']} the loop's callbacks run in C and are not charged one by one: all of the "
            f"loop thread's {result['loop_thread_ms_per_s']} ms/s shows as event loop (other) (--event-loop asyncio "
            "charges each service its callbacks)"
        )
    return (
        f"  the bench's own timing of {result['loop_callbacks_per_s']} loop callbacks/s costs ~"
        f"{result['bench_overhead_ms_per_s']} ms/s of that (charged to the services, not subtracted); by origin: "
        + ", ".join(f"{name} {rate}" for name, rate in result["loop_callbacks_per_s_by_origin"].items())
    )


def format_table(result: dict[str, Any]) -> str:
    quota = result["cpu_quota"]
    lines = [
        f"feelium bench board: {result['seconds']} s on {result['cpus']} CPUs of {result['host']['cpu_model']} (reference "
        f"workloads before / after the run: Python {result['host']['python_ms']} / {result['host_after']['python_ms']} ms, "
        f"numeric {result['host']['numeric_ms']} / {result['host_after']['numeric_ms']} ms; 1 min load before / after "
        f"{result['load_average_1min_before_after']}); rear {result['rear']}, front {result['front']}"
        + (f"; CPU quota {quota['quota_period_us']} us in {quota['cgroup']}" if quota else "")
        + f"; projected light compensated: {result['projected_light_compensation']}; motion over {result['motion_transport']}"
        + f"; event loop {result['event_loop']}",
        f"  {'service':<20} {'rate/target Hz':>16} {'miss %':>7} {'CPU ms/s':>9} {'Pi ms/s':>8}",
    ]
    for name, row in result["services"].items():
        rate = f"{row['rate_hz']}/{row['target_hz']}" if row["rate_hz"] is not None else "-"
        miss = "-" if row["miss_pct"] is None else f"{row['miss_pct']}"
        lines.append(f"  {name:<20} {rate:>16} {miss:>7} {row['cpu_ms_per_s']:>9} {row['pi_ms_per_s']:>8}")
    lines += [
        f"  process CPU ms/s {result['process_cpu_ms_per_s']}; loop lag p50 / p99 / max "
        f"{result['loop_lag_p50_ms']} / {result['loop_lag_p99_ms']} / {result['loop_lag_max_ms']} ms",
        _callbacks_line(result),
        "  flight tick late p50 / p99 (bin upper bounds): poll start {} / {} ms, controller step {} / {} ms; "
        "touch loop wake-ups per frame {}".format(*(result["services"]["flight"].get(k) for k in (
            "tick_start_late_ms_p50", "tick_start_late_ms_p99", "tick_step_late_ms_p50", "tick_step_late_ms_p99")),
            result["services"]["touch"].get("loop_wakeups_per_frame")),
        f"  RSS steady / peak {result['rss_mb']} / {result['rss_peak_mb']} MB (peak: {result['rss_peak_source']}; "
        f"sampled {result['rss_peak_sampled_mb']}; preloaded frames, "
        f"{result['preloaded_frames_mb']} MB, taken out); growth after warm-up {result['rss_growth_mb']} MB",
        f"  projected onto the Pi ({result['pi_factor']}): {result['pi_cores']} of 4 cores used, "
        f"{result['pi_cores_left']} left (all at x10: {result['pi_cores_at_10x']}, all at x6: {result['pi_cores_at_6x']}); event loop thread "
        f"{result['pi_loop_thread_cores']} of its one core",
        "  budget: " + ", ".join(f"{k} {'ok' if v else 'MISSED'}" for k, v in result["budget"].items()),
    ]
    if result.get("numeric_split"):
        shares = result["numeric_split"]["shares"]
        bound = "sampled by perf" if result["numeric_split"].get("method") == "perf" else "lower bound, profile hook"
        lines.insert(-2, f"  numeric share ({bound}, {result['numeric_split']['seconds']} s): "
                     + ", ".join(f"{name} {kind} {share:.2f}" for name, kinds in sorted(shares.items()) for kind, share in sorted(kinds.items())))
    return "\n".join(lines)


def bench_board_command(args: argparse.Namespace) -> int:
    import logging

    from feelium.daemon.journal import setup_logging

    setup_logging(logging.WARNING)
    if not args.minutes > 0:
        print("feelium bench board: --minutes must be positive", file=sys.stderr)
        return 2
    cgroup = Path(args.cgroup) if args.cgroup else None
    if args.numeric_split_seconds < 0:
        print("feelium bench board: --numeric-split-seconds must not be negative", file=sys.stderr)
        return 2
    config = load_config(args.config)
    if args.event_loop is not None:
        config = dataclasses.replace(config, daemon=dataclasses.replace(config.daemon, event_loop=args.event_loop))
    result = bench_board(config, args.minutes, front_fps=args.front_fps, cgroup=cgroup,
                         motion_transport=args.motion_transport, projected_light=args.projected_light == "on",
                         numeric_split_s=args.numeric_split_seconds, numeric_split_by=args.numeric_split_by)
    emit_report(format_table(result), result, args.json)
    return 0
