"""The numeric split behind the projection onto the Pi: numpy/OpenCV time counted per service, projected at 6x."""

from __future__ import annotations

import threading
import time

import cv2
import numpy as np
import pytest

from feelium.lab.daemon.attribution import JOB_SERVICE, OTHER_THREADS
from feelium.lab.daemon.numeric import NumericProfiler, is_numeric, numeric_shares
from feelium.lab.daemon.attribution import SIM_DEVICES
from feelium.lab.daemon.projection import PI_FACTOR, PI_FACTOR_NUMERIC, part_factor, project


def test_opencv_and_numpy_functions_are_numeric_and_python_builtins_are_not():
    a = np.zeros(4)
    assert all(is_numeric(f) for f in (cv2.GaussianBlur, cv2.remap, cv2.fisheye.undistortPoints, a.sum, np.add.reduce, np.zeros))
    assert not any(is_numeric(f) for f in ([].append, len, sorted, threading.current_thread))


def _work(blurs: int) -> None:
    image = np.random.default_rng(1).random((120, 160)).astype(np.float32)
    total = 0
    for _ in range(blurs):
        cv2.GaussianBlur(image, (0, 0), 2.0)
        total += sum(range(300))  # Python-level work beside it


def _run(name: str, job_service: str | None = None) -> float:
    """Run the work in a thread of that name; its thread CPU seconds."""
    spent = []

    def body() -> None:
        import time

        JOB_SERVICE.name = job_service
        start = time.thread_time()
        _work(60)
        spent.append(time.thread_time() - start)

    thread = threading.Thread(target=body, name=name)
    thread.start()
    thread.join()
    return spent[0]


def test_the_profiler_charges_numeric_time_to_the_service_of_the_thread_or_the_pool_job():
    profiler = NumericProfiler()
    profiler.install()
    try:
        profiler.counting = True
        touch_cpu = _run("touch-pipeline_0")
        _run("bench-pool_0", job_service="projector")
        _run("somebody-else")  # a thread no service owns: not charged
        profiler.counting = False
        _run("touch-pipeline_1")  # outside the window: not counted
    finally:
        profiler.uninstall()
    assert set(profiler.seconds) == {("touch", "thread"), ("projector", "pool")}
    assert 0 < profiler.seconds["touch", "thread"] < touch_cpu  # the blurs, not the Python loop beside them
    shares = numeric_shares(profiler.seconds, {"touch": {"thread": touch_cpu}, "projector": {"pool": 0.0}})
    assert shares == {"touch": {"thread": pytest.approx(profiler.seconds["touch", "thread"] / touch_cpu, abs=1e-3)}}


def test_each_part_is_projected_by_its_measured_share_and_the_rest_at_ten():
    result = {
        "process_cpu_ms_per_s": 200.0,
        "loop_thread_ms_per_s": 50.0,
        "rss_mb": 100.0,
        "rss_peak_mb": 110.0,
        "loop_lag_p99_ms": 1.0,
        "services": {
            "touch": {"rate_hz": 30.0, "target_hz": 30.0, "miss_pct": 0.0, "cpu_ms_per_s": 100.0,
                      "cpu_ms_per_s_by_kind": {"thread": 80.0, "loop": 20.0}},
            OTHER_THREADS: {"rate_hz": None, "target_hz": None, "miss_pct": None, "cpu_ms_per_s": 30.0,
                            "cpu_ms_per_s_by_kind": {"native-1": 30.0}},
            "flight": {"rate_hz": 50.0, "target_hz": 50.0, "miss_pct": 0.0, "cpu_ms_per_s": 50.0,
                       "cpu_ms_per_s_by_kind": {"thread": 50.0}},
        },
    }  # fmt: skip
    plain = project({**result, "services": {k: dict(v) for k, v in result["services"].items()}})
    assert plain["pi_cores"] == plain["pi_cores_at_10x"] == 2.0
    split = project(result, {"touch": {"thread": 0.5}})
    touch = 80.0 * part_factor(0.5) + 20.0 * PI_FACTOR  # 80 ms at 8x, the loop's 20 at 10x
    other = 30.0 * PI_FACTOR_NUMERIC
    flight = 50.0 * PI_FACTOR  # no share measured: Python-level
    unaccounted = (200.0 - 180.0) * PI_FACTOR
    assert result["services"]["touch"]["pi_ms_per_s"] == pytest.approx(touch)
    assert split["pi_cores"] == pytest.approx((touch + other + flight + unaccounted) / 1000.0, abs=0.01)
    assert split["pi_cores_at_6x"] <= split["pi_cores"] < split["pi_cores_at_10x"]
    assert part_factor(0.0) == PI_FACTOR and part_factor(1.0) == PI_FACTOR_NUMERIC and part_factor(7.0) == PI_FACTOR_NUMERIC


def test_the_simulated_devices_are_measured_but_not_projected():
    """The MLX90640 simulation's work is the sensor's on the blimp: out of the Pi's cores and its loop thread."""
    services = {
        "thermal": {"rate_hz": 8.0, "target_hz": 8.0, "miss_pct": 0.0, "cpu_ms_per_s": 5.0, "cpu_ms_per_s_by_kind": {"pool": 5.0}},
        SIM_DEVICES: {"rate_hz": None, "target_hz": None, "miss_pct": None, "cpu_ms_per_s": 40.0,
                      "cpu_ms_per_s_by_kind": {"pool": 30.0, "loop": 10.0}},
    }  # fmt: skip
    result = {"process_cpu_ms_per_s": 100.0, "loop_thread_ms_per_s": 110.0, "rss_mb": 100.0, "rss_peak_mb": 110.0,
              "loop_lag_p99_ms": 1.0, "services": services}
    plain = project({**result, "services": {k: dict(v) for k, v in services.items()}})
    assert plain["pi_cores"] == plain["pi_cores_at_10x"] == pytest.approx(0.6)  # (100 - 40) ms/s at 10x
    assert plain["pi_loop_thread_cores"] == pytest.approx(1.0) and not plain["budget"]["event loop thread < 1 core"]
    split = project(result, {"thermal": {"pool": 0.0}})
    assert services[SIM_DEVICES]["pi_ms_per_s"] == 0.0
    assert split["pi_cores"] == pytest.approx((5.0 + 55.0) * PI_FACTOR / 1000.0)  # thermal, and the rest unaccounted


# ---------------------------------------------------------------- the share sampled by perf
PID = 100
SCRIPT = [  # ``perf script -F comm,tid,ip,dso`` as this machine's perf 6.1 writes it
    " touch-pipeline_   101      7f3479b646b8 (/usr/lib/libpython3.11.so.1.0)",
    " touch-pipeline_   101      7f346b623bb1 (/venv/site-packages/cv2/cv2.abi3.so)",
    " touch-pipeline_   101      7f346b623bb2 (/venv/site-packages/numpy/_core/_multiarray_umath.cpython-311-x86_64-linux-gnu.so)",
    " touch-pipeline_   101      7f34798b6a9a (/usr/lib/x86_64-linux-gnu/libc.so.6)",
    " projector-rende   102      7f346b623bb1 (/venv/site-packages/cv2/cv2.abi3.so)",
    "          python   100      7f346b623bb1 (/venv/site-packages/cv2/cv2.abi3.so)",
    "          python   100      ffffffff8100 ([kernel.kallsyms])",
    "          python   103      7f346b623bb1 (/venv/site-packages/cv2/cv2.abi3.so)",
    "          python   103      ffffffff8100 ([kernel.kallsyms])",
    "    bench-pool_0   104      7f3479b646b8 (/usr/lib/libpython3.11.so.1.0)",
    "    bench-pool_1   105      7f346b623bb3 (/venv/numpy.libs/libscipy_openblas64_-32a4b2a6.so)",
    "a name with spaces 106      7f3479b646b8 (/usr/lib/libpython3.11.so.1.0)",
    "garbage",
]


def test_perf_samples_give_each_threads_numeric_share_by_the_object_they_fell_in():
    from feelium.lab.daemon.perfsplit import shares_from_script

    shares, samples = shares_from_script(SCRIPT, PID)
    assert shares["touch"]["thread"] == 0.5  # cv2 and numpy count; the interpreter and libc do not
    assert shares["projector"]["thread"] == 1.0  # "projector-render", cut to the kernel's 15 bytes
    assert shares[OTHER_THREADS]["thread"] == pytest.approx(1 / 3, abs=1e-3)  # OpenCV's threads and the stray one
    assert shares["bench-pool"]["pool"] == 0.5  # the pool as one group: the BLAS numpy calls counts
    assert "MainThread" not in shares and samples["MainThread/loop"] == 2  # the loop stays at 10x whole
    assert sum(samples.values()) == len(SCRIPT) - 1


def test_the_pools_sampled_share_goes_to_every_service_that_ran_pool_jobs():
    from feelium.lab.daemon.perfsplit import pooled_shares

    shares = {"touch": {"thread": 0.5}, "bench-pool": {"pool": 0.25}}
    charged = {"thermal": {"pool": 0.1}, "projector": {"pool": 0.02, "thread": 1.0}, "flight": {"thread": 1.0}}
    assert pooled_shares(shares, charged) == {"touch": {"thread": 0.5}, "thermal": {"pool": 0.25}, "projector": {"pool": 0.25}}


def test_a_sampled_share_of_opencvs_own_threads_replaces_the_assumed_numeric_only():
    services = {OTHER_THREADS: {"rate_hz": None, "target_hz": None, "miss_pct": None, "cpu_ms_per_s": 30.0,
                                "cpu_ms_per_s_by_kind": {"native-1": 30.0}}}  # fmt: skip
    result = {"process_cpu_ms_per_s": 30.0, "loop_thread_ms_per_s": 0.0, "rss_mb": 1.0, "rss_peak_mb": 1.0,
              "loop_lag_p99_ms": 1.0, "services": services}  # fmt: skip
    project(result, {})
    assert services[OTHER_THREADS]["pi_ms_per_s"] == 30.0 * PI_FACTOR_NUMERIC
    project(result, {OTHER_THREADS: {"thread": 0.75}})
    assert services[OTHER_THREADS]["pi_ms_per_s"] == pytest.approx(30.0 * part_factor(0.75))


def _perf_usable() -> bool:
    from feelium.lab.daemon.perfsplit import perf_usable

    return perf_usable()


@pytest.mark.skipif(not _perf_usable(), reason="Linux perf is not installed or not permitted here")
def test_perf_samples_a_named_threads_opencv_work_as_numeric(tmp_path):
    from feelium.lab.daemon.perfsplit import PerfSampler
    from feelium.priority import name_current_thread

    done = threading.Event()

    def blur() -> None:
        name_current_thread()
        image = np.random.default_rng(2).random((480, 640)).astype(np.float32)
        out = np.empty_like(image)
        while not done.is_set():
            cv2.GaussianBlur(image, (0, 0), 3.0, dst=out)

    sampler = PerfSampler(tmp_path)
    sampler.counting = True
    time.sleep(1.0)  # perf attaches to the running process (slower on a loaded machine)
    worker = threading.Thread(target=blur, name="touch-pipeline_9")
    worker.start()
    time.sleep(1.5)
    sampler.counting = False
    done.set()
    worker.join()
    shares, samples = sampler.shares()
    assert samples["touch/thread"] > 20 and shares["touch"]["thread"] > 0.8
