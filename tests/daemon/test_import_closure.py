"""What ``feelium run`` loads: the simulated daemon, run for real in a fresh process, imports no lab or command-line code."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

RUN_AND_LIST = """
import asyncio, dataclasses, json, sys
from feelium.daemon.config import Config
from feelium.daemon.runner import run_daemon, with_overrides

async def main():
    config = with_overrides(Config(), sim=True)
    config = dataclasses.replace(config, http=dataclasses.replace(config.http, port=0, token_file=sys.argv[1]))
    stop = asyncio.Event()
    asyncio.get_running_loop().call_later(30.0, stop.set)

    async def until_touch_ran(supervisor):  # the first processed frame, however loaded the machine is
        while supervisor.records["touch"].service.frames < 1:
            await asyncio.sleep(0.05)
        stop.set()

    watch = []
    supervisor = await run_daemon(config, stop=stop, on_started=lambda hub, s: watch.append(asyncio.ensure_future(until_touch_ran(s))))
    return sorted(supervisor.records)

services = asyncio.run(main())
print(json.dumps({"services": services, "modules": sorted(m for m in sys.modules if m.startswith("feelium"))}))
"""


@pytest.mark.slow
def test_the_running_daemon_loads_no_lab_or_cli_module(tmp_path):
    done = subprocess.run(
        [sys.executable, "-c", RUN_AND_LIST, str(tmp_path / "token")],
        capture_output=True, text=True, timeout=120, cwd=tmp_path, check=False,
        env=dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2])),  # this checkout's feelium
    )
    assert done.returncode == 0, done.stderr[-2000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["services"] == sorted(["audio", "flight", "front_camera", "http", "projector", "thermal", "touch"])
    modules = report["modules"]
    assert "feelium.touch.pipeline" in modules and "feelium.daemon.assembly" in modules  # it really ran
    leaked = [m for m in modules if m.startswith(("feelium.lab", "feelium.cli"))]
    assert leaked == [], leaked
