"""The two cores that step a sensor, behind one interface, and which one a sensor gets.

:class:`NumpyCore` (the readable reference, firmware_model.onboard.step) and
:class:`~firmware_model.onboard.compiled.CompiledCore` (the C99 kernel) have the same methods: ``step``,
``step_deferred``, ``refresh_ttl`` and ``step_table``, each taking the sensor's StepCache, and the attributes
``name`` (one line naming the core), ``compiled`` and ``parallel_tables`` (``step_table`` releases the GIL, so a
fleet's tables may run on threads). ``VirtualSensor`` holds one core and calls it without asking which.

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
from firmware_model.onboard.records import N_INPUTS, N_REJECT, SensorInputs, SensorState
from firmware_model.onboard.step import step, step_deferred
from firmware_model.onboard.step_cache import StepCache
from firmware_model.onboard.time_to_limit import TtlJob
from firmware_model.onboard.ttl_bound import refresh_ttl

CORES = ("auto", "c", "numpy")


def select_core(core: str, sp: SensorParams):
    """The core for ``core`` in CORES: a CompiledCore or a NumpyCore, its ``name`` saying which and, for "auto",
    why not the kernel."""
    if core not in CORES:
        raise ParameterError(f"core = {core!r} must be one of {', '.join(CORES)}")
    if core == "auto":
        core = os.environ.get("GVS_CORE", "auto").lower() or "auto"
        if core not in CORES:
            raise ParameterError(f"GVS_CORE = {core!r} must be one of {', '.join(CORES)}")
    if core == "numpy":
        return NumpyCore(sp)
    from firmware_model.onboard.compiled import CompiledCore

    try:
        return CompiledCore(sp)
    except CoreUnavailable as exc:
        if core == "c":
            raise ParameterError(f"the compiled core is unavailable: {exc}") from None
        return NumpyCore(sp, f"numpy (the compiled core is unavailable: {exc})")


class NumpyCore:
    """The numpy step (firmware_model.onboard.step) behind the CompiledCore's methods: the reference."""

    compiled = False
    parallel_tables = False

    def __init__(self, sp: SensorParams, name: str = "numpy (the reference step)"):
        self.sp, self.name = sp, name

    def step(self, state: SensorState, inputs: SensorInputs, cache: StepCache):
        """``(state, outputs)``: one step (firmware_model.onboard.step.step)."""
        return step(state, inputs, self.sp, cache)

    def step_deferred(self, state: SensorState, inputs: SensorInputs, cache: StepCache):
        """``(state, outputs, job)``: the step without its time-to-limit refresh (:meth:`refresh_ttl` does it)."""
        return step_deferred(state, inputs, self.sp, cache)

    def refresh_ttl(self, state: SensorState, job: TtlJob | None, cache: StepCache) -> SensorState:
        """The time-to-limit refresh a :meth:`step_deferred` left (None: nothing due)."""
        return refresh_ttl(state, job, self.sp, cache)

    def step_table(self, state: SensorState, raw: np.ndarray, t_s: np.ndarray, cache: StepCache, keep=None):
        """``(state, TableOutputs)``: one vehicle stepped row by row through ``raw`` (N, 8) at frame times ``t_s``
        (N,): the same TableOutputs as the compiled core's one call (``keep``: only those rows', as there)."""
        from firmware_model.onboard.compiled import TableOutputs

        N, n_pub = raw.shape[0], len(self.sp.reduced.published)
        T, lev, ttl = np.empty((N, n_pub)), np.empty((N, n_pub), dtype=np.int8), np.empty((N, n_pub))
        mode, valid = np.empty(N, dtype=np.int8), np.empty((N, 4), dtype=bool)
        innov, model_oil, rejects = np.empty(N), np.empty(N), np.empty((N, N_REJECT), dtype=np.int64)
        inlet = np.empty(N)
        for j in range(N):
            state, out = self.step(state, SensorInputs(*raw[j, :N_INPUTS].tolist(), t_s=float(t_s[j])), cache)
            st = out.status
            T[j], lev[j], ttl[j] = out.T_c, out.level, out.ttl_s
            mode[j], valid[j] = st.degraded_mode, (st.speed_valid, st.torque_valid, st.gear_valid, st.oil_valid)
            innov[j], model_oil[j], rejects[j] = st.oil_innovation_c, st.model_oil_temp_c, st.rejects
            inlet[j] = st.oil_inlet_temp_c
        out = TableOutputs(T, lev, ttl, mode, valid, innov, model_oil, rejects, inlet)
        return state, out if keep is None else TableOutputs(*(a[keep] for a in out))
