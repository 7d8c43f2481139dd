"""One BLAS thread for the onboard core, also when numpy was imported first (standard library only).

The sensor's dense linear algebra is small (61 x 61 eigen-decompositions for the time to limit). A multi-threaded
BLAS makes it *slower*: on a busy 2-core machine ``numpy.linalg.eigh`` of 61 x 61 took 6.7 ms with two OpenBLAS
threads against 0.26 ms with one, and up to 45 ms under load: the live service's 30-90 ms latency spikes. An ECU runs
the core on one core anyway.

``firmware_model/__init__.py`` sets ``OPENBLAS_NUM_THREADS=1`` (and OMP / MKL) when the user has not, which works when
firmware_model is imported before numpy (the ``gearbox-vsensor`` command). :func:`limit_blas_threads`, called when a
``VirtualSensor`` is built, does the same at run time through the loaded OpenBLAS's own setter (ctypes), the way
threadpoolctl does, so that a script importing numpy first gets it too. A thread count the user chose in
``OPENBLAS_NUM_THREADS`` before starting Python is respected.
"""

from __future__ import annotations

import ctypes
import os

#: the user's own OPENBLAS_NUM_THREADS at import time (None: not set, the sensor uses 1)
USER_SETTING = os.environ.get("OPENBLAS_NUM_THREADS")

_SETTERS = (
    "openblas_set_num_threads",
    "openblas_set_num_threads64_",
    "scipy_openblas_set_num_threads64_",
    "scipy_openblas_set_num_threads",
)
_done: set = set()


def _openblas_paths() -> set:
    try:
        with open("/proc/self/maps", encoding="ascii", errors="replace") as f:
            return {
                line.split()[-1]
                for line in f
                if "openblas" in line.lower() and line.split()[-1].startswith("/") and ".so" in line.split()[-1]
            }
    except OSError:  # not Linux: leave it to the environment variable
        return set()


def limit_blas_threads(n: int | None = None) -> int:
    """Set the thread count of every loaded OpenBLAS to ``n`` (default: the user's OPENBLAS_NUM_THREADS, else 1).
    Returns how many libraries were set; 0 when none is loaded or it cannot be reached (harmless)."""
    if n is None:
        try:
            n = int(USER_SETTING) if USER_SETTING else 1
        except ValueError:
            n = 1
    count = 0
    for path in _openblas_paths():
        if (path, n) in _done:
            count += 1
            continue
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in _SETTERS:
            fn = getattr(lib, name, None)
            if fn is not None:
                fn.argtypes = [ctypes.c_int]
                fn.restype = None
                fn(int(n))
                _done.add((path, n))
                count += 1
                break
    return count
