"""The blimp's install resolves for the Pi: aarch64, Python 3.11, numpy 1.x (docs/deploy.md, section 4).

pip resolves the project exactly as the guide installs it, but for the Pi's platform, and the test reads
pip's report. Without the constraints pip picks opencv-contrib-python-headless 5.x, whose aarch64 wheel
needs numpy >= 2 and so breaks Debian's picamera2 and simplejpeg. It needs the package index, so it
skips (saying so) when the index cannot be reached.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CONSTRAINTS = ROOT / "constraints" / "pi-bookworm.txt"
INDEX = os.environ.get("PIP_INDEX_URL", "https://pypi.org/simple").rstrip("/")


def _pinned(name: str) -> str:
    """The version the constraints file pins ``name`` to."""
    for line in CONSTRAINTS.read_text(encoding="utf-8").splitlines():
        requirement = line.split("#", 1)[0].strip()
        if requirement.startswith(f"{name}=="):
            return requirement.split("==", 1)[1]
    raise AssertionError(f"{CONSTRAINTS} does not pin {name}")


def _index_reachable() -> bool:
    try:
        with urllib.request.urlopen(f"{INDEX}/numpy/", timeout=10):
            return True
    except (urllib.error.URLError, OSError):
        return False


@pytest.fixture(scope="module")
def pi_report(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """name -> version of everything pip would install on the Pi, from ``pip install --dry-run --report``."""
    if not _index_reachable():
        pytest.skip(f"the package index {INDEX} is unreachable: cannot resolve the Pi install offline")
    report = tmp_path_factory.mktemp("pi") / "report.json"
    command = [
        sys.executable, "-m", "pip", "install", "--dry-run", "--quiet", "--ignore-installed",
        "--report", str(report), "--target", str(report.parent / "unused"),
        "--platform", "manylinux2014_aarch64", "--python-version", "3.11", "--implementation", "cp", "--abi", "cp311",
        "--only-binary=:all:", "-c", str(CONSTRAINTS), str(ROOT),
    ]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stderr[-2000:]
    installs = json.loads(report.read_text(encoding="utf-8"))["install"]
    return {item["metadata"]["name"].lower(): item["metadata"]["version"] for item in installs}


def test_pi_install_keeps_numpy_1(pi_report: dict[str, str]) -> None:
    assert int(pi_report["numpy"].split(".")[0]) == 1, pi_report["numpy"]


def test_pi_install_takes_the_pinned_opencv(pi_report: dict[str, str]) -> None:
    assert pi_report["opencv-contrib-python-headless"] == _pinned("opencv-contrib-python-headless")
    assert "opencv-python" not in pi_report and "opencv-python-headless" not in pi_report


def test_pi_install_brings_feelium_and_its_dependencies(pi_report: dict[str, str]) -> None:
    assert {"feelium", "aiohttp", "pyserial", "smbus2", "uvloop"} <= pi_report.keys()  # uvloop: an aarch64 wheel
