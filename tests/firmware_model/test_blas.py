"""The onboard core pins BLAS to one thread even when numpy was imported first (firmware_model.onboard.blas)."""

import ctypes
import subprocess
import sys

import numpy as np

from firmware_model.onboard.blas import _openblas_paths, limit_blas_threads


def test_limit_blas_threads_sets_the_loaded_openblas():
    np.linalg.eigh(np.eye(4))  # make sure the library is loaded
    paths = _openblas_paths()
    if not paths:  # a numpy without OpenBLAS (e.g. Accelerate, MKL): nothing to do
        assert limit_blas_threads() == 0
        return
    assert limit_blas_threads(1) >= 1
    getters = (
        "openblas_get_num_threads",
        "openblas_get_num_threads64_",
        "scipy_openblas_get_num_threads64_",
        "scipy_openblas_get_num_threads",
    )
    for path in paths:
        lib = ctypes.CDLL(path)
        get = next((getattr(lib, g) for g in getters if hasattr(lib, g)), None)
        if get is not None:
            assert get() == 1


def test_building_a_sensor_pins_blas_after_numpy_was_imported_first():
    code = (
        "import os; os.environ.pop('OPENBLAS_NUM_THREADS', None)\n"
        "import numpy, ctypes\n"
        "from firmware_model.onboard import blas\n"
        "paths = blas._openblas_paths()\n"
        "lib = ctypes.CDLL(next(iter(paths))) if paths else None\n"
        "get = next((getattr(lib, g) for g in ('openblas_get_num_threads', 'openblas_get_num_threads64_',"
        " 'scipy_openblas_get_num_threads64_') if lib is not None and hasattr(lib, g)), None)\n"
        "print(-1 if get is None else get(), end=' ')\n"
        "from firmware_model.parameters import load_parameters\n"
        "from firmware_model.onboard.sensor import VirtualSensor\n"
        "VirtualSensor(load_parameters('GRS905'))\n"
        "print(-1 if get is None else get())\n"
    )
    env = {"PATH": "/usr/bin:/bin", "OMP_NUM_THREADS": "2"}
    import os

    env.update({k: v for k, v in os.environ.items() if k in ("PYTHONPATH", "HOME")})
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr
    before, after = (int(x) for x in res.stdout.split())
    if after == -1:
        return  # no OpenBLAS getter to check against on this numpy
    assert after == 1
