"""The flight tick's own Python, without the port, the board or the threads: CPU per tick of the client's poll and
motor command, and of the controller's step, replayed from a recorded simulated flight.

    python benchmarks/flight_step_cost.py [--seconds 12] [--repeats 7] [--paced] [--json FILE]

Why a replay: on the real path (``flight_tick_cost.py``) a tick's CPU mixes the system calls, the thread hand-off
and the emulated board's process; this one times only what a speed-up of the tick's code can change, the same
inputs every run, so an A/B between two worktrees compares code, not load. A seeded flight (the pinned tick
test's script: hold, every motion command, softening, a climb, rangefinder dropouts, drafts) is run once on the
simulated board with every byte the link returned recorded; then, ``--repeats`` times, a fresh client is fed the
recorded bytes (what it writes is only counted) and a fresh controller the recorded telemetry and setpoints,
each timed with the thread's CPU clock. It checks that the replay computes what the flight did (the same motor
microseconds every tick) and prints the median and the least of the repeats per tick (on a loaded machine the least is the one to compare).

Back to back, the code and its data stay in the CPU's caches; in the daemon a tick runs once every 20 ms
after other threads have run, and the same work costs about three times as much (0.42 against 0.14 ms a tick
on this machine). ``--paced`` replays once more at 50 Hz (sleeping out each period, ``--seconds`` long) and
reports that figure too: the one that multiplies into the daemon's CPU.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import deque
from typing import Any

from feelium.daemon.config import Config
from feelium.flight.blimp_model import DraftParams
from feelium.flight.client import MspClient
from feelium.flight.controller import FlightController
from feelium.flight.setpoint import HOLD, Setpoint, setpoint_for_motion
from feelium.flight.sim_board import BoardParams, SensorParams, SimSerial, board_with
from feelium.flight.telemetry import Telemetry
from feelium.lab.flight.simulation import SimFlight
from feelium.lab.report import print_and_save

CONFIG = Config().flight
SCRIPT = (  # (until s, motion command); the pinned tick test's flight without its absolute setpoint
    (1.5, None), (3.0, "forward"), (4.0, None), (5.2, "turn_right"), (6.0, None), (7.0, "up"),
    (7.6, None), (8.4, "down"), (9.0, "soften"), (10.0, "backward"), (10.8, "turn_left"), (12.0, None),
)


def _setpoint(t: float) -> Setpoint:
    for until, what in SCRIPT:
        if t < until:
            return setpoint_for_motion(None if what == "soften" else what, CONFIG, soften=what == "soften")
    return HOLD


class _RecordingLink:
    """The simulated board's link, keeping every answer it gave (``in_waiting`` and ``read``) in order."""

    def __init__(self, link: SimSerial) -> None:
        self.link = link
        self.answers: list[Any] = []

    @property
    def in_waiting(self) -> int:
        value = self.link.in_waiting
        self.answers.append(value)
        return value

    def write(self, data: bytes) -> int:
        return self.link.write(data)

    def read(self, size: int = 1) -> bytes:
        data = self.link.read(size)
        self.answers.append(data)
        return data

    def close(self) -> None:
        self.link.close()


class _ReplayLink:
    """Gives back the recorded answers in order; a client that asks differently runs out or gets a wrong type."""

    def __init__(self, answers: list[Any]) -> None:
        self._answers = deque(answers)
        self.written = 0

    @property
    def in_waiting(self) -> int:
        value = self._answers.popleft()
        assert isinstance(value, int), "the replayed client asked the link something else than the recorded one"
        return value

    def write(self, data: bytes) -> int:
        self.written += len(data)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        value = self._answers.popleft()
        assert isinstance(value, bytes), "the replayed client asked the link something else than the recorded one"
        return value

    def close(self) -> None:
        pass


def record(seconds: float) -> tuple[list[float], list[Any], list[tuple[float, Telemetry | None, Setpoint]], list[tuple[int, ...]]]:
    """Fly the seeded flight once: tick times, the link's answers, the controller's inputs and its motor commands."""
    board = board_with(BoardParams(drafts=DraftParams(), sensors=SensorParams(range_dropout_probability=0.1)), z=1.5)
    flight = SimFlight(CONFIG, board, seed=7)
    recording = _RecordingLink(flight.link)  # type: ignore[arg-type]
    flight.link = flight.client.link = recording  # type: ignore[assignment]
    flight.client._read_some = lambda: recording.read(max(1, recording.in_waiting))
    inputs: list[tuple[float, Telemetry | None, Setpoint]] = []
    controller = flight.controller
    step = controller.step

    def recorded_step(t: float, telemetry: Telemetry | None, setpoint: Setpoint) -> Any:
        inputs.append((t, telemetry, setpoint))
        return step(t, telemetry, setpoint)

    controller.step = recorded_step  # type: ignore[method-assign]
    ticks, motors = [], []
    end = seconds - 1e-9
    while flight.t < end:
        out = flight.step(_setpoint(flight.t + flight.period))
        ticks.append(flight.t)
        motors.append(out.motors_us)
    return ticks, recording.answers, inputs, motors


def replay_client(ticks: list[float], answers: list[Any], motors: list[tuple[int, ...]]) -> tuple[float, list[Telemetry]]:
    """CPU seconds of every tick's poll and motor command, fed the recorded bytes; the telemetry it decoded."""
    now = [0.0]
    client = MspClient(_ReplayLink(answers), timeout_s=CONFIG.reply_timeout_s, clock=lambda: now[0])
    client._read_some = lambda: client.link.read(max(1, client.link.in_waiting))  # as recorded
    every = CONFIG.battery_every
    polled = []
    start = time.thread_time()
    for cycle, (t, motors_us) in enumerate(zip(ticks, motors)):
        now[0] = t
        polled.append(client.poll(with_battery=cycle % every == 0))
        client.send_motors(motors_us)
    return time.thread_time() - start, polled


def replay_controller(inputs: list[tuple[float, Telemetry | None, Setpoint]]) -> tuple[float, list[tuple[int, ...]]]:
    """CPU seconds of a fresh controller's steps on the recorded inputs; its motor commands."""
    controller = FlightController(CONFIG)
    step = controller.step
    start = time.thread_time()
    outs = [step(t, telemetry, setpoint) for t, telemetry, setpoint in inputs]
    return time.thread_time() - start, [out.motors_us for out in outs]


def replay_paced(ticks: list[float], answers: list[Any], inputs: list[tuple[float, Telemetry | None, Setpoint]],
                 motors: list[tuple[int, ...]]) -> tuple[float, float]:
    """CPU seconds of the client's and the controller's part of every tick, one tick per control period."""
    now = [0.0]
    client = MspClient(_ReplayLink(answers), timeout_s=CONFIG.reply_timeout_s, clock=lambda: now[0])
    client._read_some = lambda: client.link.read(max(1, client.link.in_waiting))
    controller = FlightController(CONFIG)
    period, every = 1.0 / CONFIG.rate_hz, CONFIG.battery_every
    client_s = controller_s = 0.0
    due = time.monotonic()
    for cycle, (t, (step_t, telemetry, setpoint), motors_us) in enumerate(zip(ticks, inputs, motors)):
        due += period
        time.sleep(max(0.0, due - time.monotonic()))
        now[0] = t
        start = time.thread_time()
        client.poll(with_battery=cycle % every == 0)
        stepped = time.thread_time()
        out = controller.step(step_t, telemetry, setpoint)
        sent = time.thread_time()
        client.send_motors(motors_us)
        end = time.thread_time()
        assert out.motors_us == motors_us, "the paced controller commanded other motors than the flight"
        client_s += (stepped - start) + (end - sent)
        controller_s += sent - stepped
    return client_s, controller_s


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=12.0, help="simulated flight recorded")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--paced", action="store_true", help="also replay once at the control rate (cold caches)")
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    ticks, answers, inputs, motors = record(args.seconds)
    telemetry = [tel for _, tel, _ in inputs]
    client_s, controller_s = [], []
    for _ in range(args.repeats):
        seconds, polled = replay_client(ticks, answers, motors)
        assert polled == telemetry, "the replayed client decoded other telemetry than the flight"
        client_s.append(seconds)
        seconds, commanded = replay_controller(inputs)
        assert commanded == motors, "the replayed controller commanded other motors than the flight"
        controller_s.append(seconds)
    n = len(ticks)
    client_ms, controller_ms = 1000.0 * statistics.median(client_s) / n, 1000.0 * statistics.median(controller_s) / n
    report = {
        "ticks": n,
        "repeats": args.repeats,
        "client_ms_per_tick": round(client_ms, 4),
        "controller_ms_per_tick": round(controller_ms, 4),
        "ms_per_tick": round(client_ms + controller_ms, 4),
        "client_ms_min": round(1000.0 * min(client_s) / n, 4),  # the least disturbed run: compare these under load
        "controller_ms_min": round(1000.0 * min(controller_s) / n, 4),
        "client_ms_runs": [round(1000.0 * s / n, 4) for s in client_s],
        "controller_ms_runs": [round(1000.0 * s / n, 4) for s in controller_s],
    }
    if args.paced:
        client_paced, controller_paced = replay_paced(ticks, answers, inputs, motors)
        report["paced_client_ms_per_tick"] = round(1000.0 * client_paced / n, 4)
        report["paced_controller_ms_per_tick"] = round(1000.0 * controller_paced / n, 4)
        report["paced_ms_per_tick"] = round(1000.0 * (client_paced + controller_paced) / n, 4)
    print_and_save(report, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
