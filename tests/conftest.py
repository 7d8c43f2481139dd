"""Test session set-up: one BLAS thread, as the onboard core runs (see firmware_model/__init__.py)."""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
