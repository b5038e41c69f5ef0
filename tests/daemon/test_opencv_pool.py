"""Before anything imports cv2 or numpy (feelium/__init__.py), the package keeps OpenCV's thread pool from
spinning and OpenBLAS from starting threads."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NAMES = ("OPENCV_THREAD_POOL_ACTIVE_WAIT_WORKER", "OPENCV_THREAD_POOL_ACTIVE_WAIT_MAIN")


def _environment_seen_by_cv2(env: dict[str, str]) -> list[str]:
    """What the two variables hold when ``python -m feelium``'s first import of cv2 happens."""
    code = (
        "import sys, os, builtins\n"
        "seen = []\n"
        "real = builtins.__import__\n"
        "def spy(name, *a, **k):\n"
        "    if name == 'cv2' and not seen:\n"
        f"        seen.extend(os.environ.get(n, '') for n in {NAMES!r})\n"
        "    return real(name, *a, **k)\n"
        "builtins.__import__ = spy\n"
        "import feelium.cli\n"
        "print(','.join(seen))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    return out.stdout.strip().split(",")


def test_no_active_wait_is_set_before_cv2_is_imported() -> None:
    env = {k: v for k, v in os.environ.items() if k not in NAMES}
    assert _environment_seen_by_cv2(env) == ["0", "0"]


def test_a_value_in_the_environment_wins() -> None:
    env = {**os.environ, NAMES[0]: "2000", NAMES[1]: "10000"}
    assert _environment_seen_by_cv2(env) == ["2000", "10000"]


def test_numpy_and_opencv_start_no_blas_threads_under_the_package() -> None:
    """OpenBLAS (numpy's and OpenCV's copy) starts a thread per core at load unless told otherwise."""
    code = "import feelium, numpy, cv2; print(open('/proc/self/status').read().split('Threads:')[1].split()[0])"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "1"  # the main thread alone
