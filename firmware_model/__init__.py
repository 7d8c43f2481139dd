"""What runs onboard: the physics the sensor needs, the reduced thermal network and its fixed step,
warnings, and the CAN service. Depends on numpy and the standard library only."""

import os as _os

# The onboard core is single-threaded by design (an ECU has one core for it). numpy's multi-threaded BLAS makes the
# small dense linear algebra of the time to limit (61 x 61 eigen-decompositions) ~25x *slower* on a busy 2-core
# machine (thread hand-off: 6.7 ms instead of 0.26 ms) and gave the live service its 30-90 ms latency spikes. One
# BLAS thread unless the user chose otherwise; effective when firmware_model is imported before numpy (the
# gearbox-vsensor command does so); firmware_model.onboard.blas also sets it at run time when a VirtualSensor is built.
from firmware_model.onboard import blas as _blas  # noqa: E402,F401  (records the user's own setting first)

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
del _var

__version__ = "0.1.0"
