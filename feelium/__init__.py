"""Feelium: onboard software of a touchable telepresence blimp."""

import os as _os

__version__ = "0.1.0"

# OpenCV's thread pool (pthreads) spins between jobs: its workers and the caller busy-wait for the next
# parallel_for instead of sleeping, which in the daemon (a warp and a touch frame 30 times a second, idle in
# between) cost a whole OpenCV worker thread's worth of CPU for nothing (docs/performance.md: "OpenCV's
# thread pool"). The daemon runs OpenCV on one thread since session 24 (``[daemon] opencv_threads``); where a
# pool is used (that setting at 0, the lab's tools) it sleeps between jobs. OpenCV reads these once, when cv2 is
# first imported, so they are set here, before any module of the package can import it; a value in the
# environment wins.
for _name in ("OPENCV_THREAD_POOL_ACTIVE_WAIT_WORKER", "OPENCV_THREAD_POOL_ACTIVE_WAIT_MAIN"):
    _os.environ.setdefault(_name, "0")
del _name

# numpy's and OpenCV's OpenBLAS each start a thread per core when they load. The daemon's BLAS work is vector
# dots and a small least-squares fit when a calibration is built, which never splits over threads, so those
# threads (three each on the Pi) only cost their stacks and buffers. Read once, at load: set here, before any
# module of the package imports numpy; a value in the environment wins.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
