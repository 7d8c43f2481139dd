"""Which core steps a sensor (the compiled C kernel or the numpy reference) and the numpy core's table loop.

``core="auto"`` takes the kernel when it loads (firmware_model.onboard.ckernel: built by ``pip install``, or
compiled on first use when a C compiler is present) and otherwise the numpy step, saying why; ``"c"`` insists on
the kernel; ``"numpy"`` is the readable reference. ``GVS_CORE=numpy|c`` in the environment overrides "auto".
"""
from __future__ import annotations

import os

import numpy as np

from firmware_model.errors import ParameterError
from firmware_model.onboard.ckernel import CoreUnavailable
from firmware_model.onboard.params import SensorParams
from firmware_model.onboard.records import N_INPUTS, N_PUB, SensorInputs

CORES = ("auto", "c", "numpy")


def select_core(core: str, sp: SensorParams):
    """``(CompiledCore or None, one line naming the core)`` for ``core`` in CORES."""
    if core not in CORES:
        raise ParameterError(f"core = {core!r} must be one of {', '.join(CORES)}")
    if core == "auto":
        core = os.environ.get("GVS_CORE", "auto").lower() or "auto"
        if core not in CORES:
            raise ParameterError(f"GVS_CORE = {core!r} must be one of {', '.join(CORES)}")
    if core == "numpy":
        return None, "numpy (the reference step)"
    from firmware_model.onboard.compiled import CompiledCore
    try:
        compiled = CompiledCore(sp)
    except CoreUnavailable as exc:
        if core == "c":
            raise ParameterError(f"the compiled core is unavailable: {exc}") from None
        return None, f"numpy (the compiled core is unavailable: {exc})"
    return compiled, "c (the compiled C99 kernel, double)"


def step_table_numpy(sensor, state, raw: np.ndarray, t_s: np.ndarray):
    """The numpy core's :meth:`VirtualSensor.step_table`: row by row, the same TableOutputs."""
    from firmware_model.onboard.compiled import TableOutputs
    N = raw.shape[0]
    T, lev, ttl = np.empty((N, N_PUB)), np.empty((N, N_PUB), dtype=np.int8), np.empty((N, N_PUB))
    mode, valid = np.empty(N, dtype=np.int8), np.empty((N, 4), dtype=bool)
    innov, model_oil, rejects = np.empty(N), np.empty(N), np.empty((N, len(sensor.reject_reasons)), dtype=np.int64)
    for j in range(N):
        state, out = sensor.step(state, SensorInputs(*raw[j, :N_INPUTS].tolist(), t_s=float(t_s[j])))
        st = out.status
        T[j], lev[j], ttl[j] = out.T_c, out.level, out.ttl_s
        mode[j], valid[j] = st.degraded_mode, (st.speed_valid, st.torque_valid, st.gear_valid, st.oil_valid)
        innov[j], model_oil[j], rejects[j] = st.oil_innovation_c, st.model_oil_temp_c, st.rejects
    return state, TableOutputs(T, lev, ttl, mode, valid, innov, model_oil, rejects)
