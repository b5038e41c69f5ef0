"""A real ``feelium run --sim`` on a loopback port, for the end-to-end tests of the headset link and for
``feelium bench link``'s abuse phase (which needs the whole daemon: its projector decodes faces, its memory is what
counts)."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from dataclasses import dataclass
from pathlib import Path

TOKEN = "live-test-token-0123456789abcdef"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class LiveDaemon:
    process: subprocess.Popen
    port: int
    token: str
    log_path: Path

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def api(self) -> str:
        return f"{self.base}/api/v1"

    @property
    def auth(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"}

    def health(self) -> dict:
        with urllib.request.urlopen(urllib.request.Request(f"{self.api}/health", headers=self.auth), timeout=5) as resp:
            return json.load(resp)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")[-4000:]


# Short waits so the tests' clients are dropped or answered quickly; the benchmark keeps the shipped ones.
TEST_TIMEOUTS = """
longpoll_max_s = 1.0
stream_write_timeout_s = 0.5
keepalive_s = 1.0
"""


def start_daemon(tmp: Path, extra_toml: str = "", startup_s: float = 60.0, http_toml: str = TEST_TIMEOUTS) -> LiveDaemon:
    """Start the daemon in sim mode and wait (bounded) until the API answers and a front frame exists."""
    port = free_port()
    config = tmp / "feelium.toml"
    config.write_text(
        f"""
[http]
host = "127.0.0.1"
port = {port}
token = "{TOKEN}"
token_file = "{tmp / 'token'}"
{http_toml}
[audio]
backend = "sim"

[sim]
autoplay = false
{extra_toml}
"""
    )
    log_path = tmp / "daemon.log"
    with open(log_path, "wb") as log:
        process = subprocess.Popen(
            [sys.executable, "-m", "feelium", "run", "--sim", "--config", str(config)],
            stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )  # fmt: skip
    daemon = LiveDaemon(process, port, TOKEN, log_path)
    deadline = time.monotonic() + startup_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"the daemon exited with {process.returncode}:\n{daemon.log()}")
        try:
            req = urllib.request.Request(f"{daemon.api}/video/front.jpg", headers=daemon.auth)
            with urllib.request.urlopen(req, timeout=2) as resp:
                if resp.status == 200:
                    return daemon
        except OSError:
            pass
        time.sleep(0.2)
    stop_daemon(daemon)
    raise RuntimeError(f"the daemon did not serve a front frame within {startup_s} s:\n{daemon.log()}")


def stop_daemon(daemon: LiveDaemon) -> None:
    if daemon.process.poll() is None:
        daemon.process.send_signal(signal.SIGTERM)
        try:
            daemon.process.wait(10)
        except subprocess.TimeoutExpired:
            daemon.process.kill()
            daemon.process.wait(5)
