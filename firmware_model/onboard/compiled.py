"""The onboard step on the compiled C kernel: the same records in and out as the numpy step
(firmware_model.onboard.step), bit for bit in the integer outputs and within rounding in the temperatures.

:class:`CompiledCore` holds the kernel's tables for one :class:`~firmware_model.onboard.params.SensorParams`
(firmware_model.onboard.kernel_tables) and steps :class:`~firmware_model.onboard.records.SensorState` records:

* :meth:`CompiledCore.step_deferred` / :meth:`CompiledCore.refresh_ttl`: one step of one vehicle (batch shape ())
  or of a batch (V,) in one call into C;
* :meth:`CompiledCore.step_table`: a whole table of one vehicle's inputs in one call (the kernel refreshes the time
  to limit in place; it stops only before a forward time jump, which the host propagates; docs/sensor.md).

The states it returns are :class:`BufferedState` records: their arrays are views into one buffer of the kernel's
``gvs_state`` structs, so that the next step hands that buffer to C without packing. Everything else (the numpy
step, snapshots, the service) reads them as any SensorState. The time-to-limit refresh runs in the kernel
(``gvs_ttl_refresh``: :meth:`CompiledCore.refresh_ttl` after a step, in place inside a table's ``gvs_run``); one
part stays on the host, in numpy, as the kernel's header says: the propagation of the state over a forward time
jump (firmware_model.onboard.held_inputs.jump_state).
"""

from __future__ import annotations

import ctypes as C
from typing import NamedTuple

import numpy as np

from firmware_model.onboard.ckernel import TABLE_FIELDS, CoreUnavailable, load
from firmware_model.onboard.held_inputs import jump_state
from firmware_model.onboard.kernel_interface import NEED_JUMP
from firmware_model.onboard.kernel_tables import VEHICLE_EFFECTS, table_arrays, vehicle_arrays
from firmware_model.onboard.params import SensorParams, boundary_change_steps
from firmware_model.onboard.records import I_OIL, N_INPUTS, SensorInputs, SensorOutputs, SensorState, SensorStatus
from firmware_model.onboard.step_cache import StepCache
from firmware_model.onboard.time_to_limit import TtlJob, TtlPoint


class BufferedState(SensorState):
    """A SensorState whose arrays are views into ``buf`` (the kernel's gvs_state structs, batch shape B), made by
    the CompiledCore ``owner``."""

    buf: np.ndarray
    owner: object

    def __reduce__(self):
        """Pickled (sent to another process) as a plain SensorState of copies: the buffer and its core stay here."""
        return SensorState, tuple(np.array(a) for a in self)


#: rows per kernel call of a table (two reused buffers of this many records instead of one per row)
TABLE_CHUNK = 8192


class TableOutputs(NamedTuple):
    """The outputs of every step of a table (N rows)."""

    T_c: np.ndarray  # (N, 28)
    level: np.ndarray  # (N, 28) int8
    ttl_s: np.ndarray  # (N, 28)
    degraded_mode: np.ndarray  # (N,) int8
    valid: np.ndarray  # (N, 4) bool: speed, torque, gear, oil valid
    oil_innovation_c: np.ndarray
    model_oil_temp_c: np.ndarray
    rejects: np.ndarray  # (N, 13) cumulative counters after each step
    oil_inlet_temp_c: np.ndarray  # (N,) a forced oil system's inlet (SensorStatus.oil_inlet_temp_c); else NaN


class CompiledCore:
    """The kernel's tables for one sensor's parameters, and its steps on SensorState records (the methods of
    firmware_model.onboard.core_select.NumpyCore, in C)."""

    compiled = True
    #: the kernel call releases the GIL and shares only read-only tables: tables may run on threads
    parallel_tables = True

    def __init__(self, sp: SensorParams, real: str = "double"):
        self.lib, self.S = load(real)
        self.sp, self.real = sp, real
        self.name = f"c (the compiled C99 kernel, {real})"
        rp = sp.reduced
        self.n, self.ns, self.nl, self.nb = rp.n, rp.src_matrix.shape[0], len(rp.link_a), len(rp.bc_default_c)
        self.n_pub = len(rp.published)  # the structs hold GVS_MAX_PUB: the first n_pub are this gearbox's
        arrays = table_arrays(sp)
        self.nst = int(arrays["nst"])
        self._keep, self.tables = [], self.S["Tables"]()
        for name, kind in TABLE_FIELDS:
            setattr(self.tables, name, self._field(arrays[name], kind))
        self._tables_p = C.byref(self.tables)
        if self.lib.gvs_check_tables(self._tables_p) != 0:
            raise CoreUnavailable("this gearbox's onboard network exceeds the C kernel's capacities")
        self._vehicles: dict = {}

    def __reduce__(self):
        """Pickled as what it is built from (the library and its pointers are rebuilt in the other process)."""
        return CompiledCore, (self.sp, self.real)

    def _field(self, value, kind: str):
        if kind == "i":
            return int(value)
        if kind == "r":
            return float(value)
        dtype, ctype = (
            (self.S["real"], C.c_double if self.real == "double" else C.c_float)
            if kind == "pr"
            else (np.int32, C.c_int32)
        )
        a = np.ascontiguousarray(value, dtype=dtype)
        if a.size == 0:
            a = np.zeros(1, dtype=dtype)  # a valid pointer for an empty table
        self._keep.append(a)
        return a.ctypes.data_as(C.POINTER(ctype))

    def vehicles(self, V: int | None) -> np.ndarray:
        """The gvs_vehicle records (V,) of a batch (None: one vehicle), built once per batch size."""
        key = V
        if key not in self._vehicles:
            arr = vehicle_arrays(self.sp, V)
            rec = np.zeros(arr["src_scale"].shape[0], dtype=self.S["Vehicle_dtype"])
            rec["src_scale"][:, : arr["src_scale"].shape[1]] = arr["src_scale"]
            for k in VEHICLE_EFFECTS:
                rec[k] = arr[k]
            rec["T_bc_default_c"][:, : self.nb] = arr["T_bc_default_c"]
            self._vehicles[key] = rec
        return self._vehicles[key]

    # -- records <-> structs

    def pack(self, state: SensorState) -> np.ndarray:
        """A fresh gvs_state buffer (batch shape B) holding ``state``."""
        buf = getattr(state, "buf", None)
        if isinstance(state, BufferedState) and buf is not None:
            buf = buf.copy()
            if getattr(state, "owner", None) is not self:
                buf["memo_valid"] = buf["memo_heat_valid"] = 0  # another sensor's memos: not this one's
            return buf
        B = np.shape(state.t_last_s)
        buf = np.zeros(B, dtype=self.S["State_dtype"])
        buf["T_c"][..., : self.n] = state.T_c
        buf["lag_w"][..., : state.lag_w.shape[-1]] = state.lag_w
        for f in (
            "hold",
            "age_s",
            "same_s",
            "raw_prev",
            "oil_ref_c",
            "t_last_s",
            "k",
            "rejects",
            "recover_s",
        ):
            buf[f] = getattr(state, f)
        for f in ("pending_s", "ttl_s", "level"):
            buf[f][..., : self.n_pub] = getattr(state, f)
        return buf

    def unpack(self, buf: np.ndarray) -> BufferedState:
        """A SensorState of views into ``buf``."""
        st = BufferedState(
            buf["T_c"][..., : self.n],
            buf["lag_w"][..., : self.ns],
            buf["hold"],
            buf["age_s"],
            buf["same_s"],
            buf["raw_prev"],
            buf["oil_ref_c"],
            buf["level"][..., : self.n_pub],
            buf["pending_s"][..., : self.n_pub],
            buf["ttl_s"][..., : self.n_pub],
            buf["t_last_s"],
            buf["k"],
            buf["rejects"],
            buf["recover_s"],
        )
        st.buf, st.owner = buf, self
        return st

    def inputs(self, inputs: SensorInputs, B: tuple) -> np.ndarray:
        rec = np.empty(B, dtype=self.S["Inputs_dtype"])
        raw = rec["raw"]
        for i in range(N_INPUTS):
            raw[..., i] = inputs[i]
        rec["t_s"] = inputs.t_s
        return rec

    def outputs(self, out: np.ndarray) -> SensorOutputs:
        status = SensorStatus(
            out["degraded_mode"].copy(),
            out["speed_valid"] != 0,
            out["torque_valid"] != 0,
            out["gear_valid"] != 0,
            out["oil_valid"] != 0,
            out["valid_flags"].astype(np.int64),
            out["model_oil_temp_c"].astype(float),
            out["oil_innovation_c"].astype(float),
            out["oil_source"].copy(),
            out["frozen_flags"].astype(np.int64),
            out["rejects"].copy(),
            out["oil_inlet_temp_c"].astype(float),
        )
        pub = slice(0, self.n_pub)
        T_c, level, ttl_s = out["T_c"][..., pub], out["level"][..., pub], out["ttl_s"][..., pub]
        return SensorOutputs(T_c.astype(float), level.copy(), ttl_s.astype(float), status)

    def ttl_job(self, pts: np.ndarray) -> TtlJob | None:
        """The time-to-limit refreshes the kernel's points ask for (None: none due)."""
        due = pts["due"] != 0
        if not due.any():
            return None
        vehicles = (
            ((),)
            if not pts.shape
            else tuple((int(i),) for i in np.flatnonzero(due))
            if pts.ndim == 1
            else tuple(v for v in np.ndindex(pts.shape) if due[v])
        )
        n, ns, nl, nst, nb = self.n, self.ns, self.nl, self.nst, self.nb

        def points():  # made only when asked (a numpy refresh, a test): TtlJob
            return tuple(
                TtlPoint(
                    p["T_main_c"][:n].astype(float),
                    p["src_w"][:ns].astype(float),
                    p["G_w_per_k"][:nl].astype(float),
                    p["G_streams_w_per_k"][:nst].astype(float),
                    float(p["dT_in_k"]),
                    float(p["Q_cool_w"]),
                    bool(p["measured"]),
                    int(p["row"]),
                    float(p["omega_in_rad_s"]),
                    float(p["T_oil_c"]),
                    p["T_bc_c"][:nb].astype(float),
                    p["used"].astype(float),
                    float(p["rho_cp_j_per_m3k"]),
                )
                for p in (pts[v] for v in vehicles)
            )

        return TtlJob(vehicles, points, pts)

    # -- steps

    def step(self, state: SensorState, inputs: SensorInputs, cache: StepCache):
        """``(state, outputs)`` as firmware_model.onboard.step.step, in C."""
        state, outputs, job = self.step_deferred(state, inputs, cache)
        return self.refresh_ttl(state, job, cache), outputs

    def step_deferred(self, state: SensorState, inputs: SensorInputs, cache: StepCache):
        """``(state, outputs, job)`` as firmware_model.onboard.step.step_deferred, in C."""
        buf = self.pack(state)
        B = buf.shape
        if not B:
            return self._step_one(buf, inputs, cache)
        rec = self.inputs(inputs, B)
        jump = self._jumps(buf, rec, cache)
        out = np.zeros(B, dtype=self.S["Outputs_dtype"])
        pts = np.zeros(B, dtype=self.S["TtlPoint_dtype"])
        veh = self.vehicles(B[0])
        self.lib.gvs_step_batch(
            self._tables_p,
            veh.ctypes.data,
            1 if veh.shape[0] > 1 else 0,
            int(np.prod(B, dtype=np.int64)),
            buf.ctypes.data,
            rec.ctypes.data,
            jump.ctypes.data,
            out.ctypes.data,
            pts.ctypes.data,
            None,
        )
        return self.unpack(buf), self.outputs(out), self.ttl_job(pts)

    def _step_one(self, buf: np.ndarray, inputs: SensorInputs, cache: StepCache):
        """One vehicle: one gvs_step (a second one after a forward jump propagated on the host)."""
        rec = self.inputs(inputs, ())
        out = np.zeros((), dtype=self.S["Outputs_dtype"])
        pts = np.zeros((), dtype=self.S["TtlPoint_dtype"])
        args = (
            self._tables_p,
            self.vehicles(None).ctypes.data_as(C.POINTER(self.S["Vehicle"])),
            buf.ctypes.data,
            rec.ctypes.data,
        )
        if self.lib.gvs_step(*args, 0, out.ctypes.data, pts.ctypes.data) == NEED_JUMP:
            gap = float(rec["t_s"]) - float(buf["t_last_s"])
            st = jump_state(self.unpack(buf), gap - self.sp.dt_s, self.sp, cache, rec["raw"][I_OIL])
            buf["T_c"][:, : self.n], buf["pending_s"][: self.n_pub] = st.T_c, st.pending_s
            self.lib.gvs_step(*args, 1, out.ctypes.data, pts.ctypes.data)
        return self.unpack(buf), self.outputs(out), self.ttl_job(pts)

    def _jumps(self, buf: np.ndarray, rec: np.ndarray, cache: StepCache) -> np.ndarray:
        """Forward time jumps propagated on the host (held_inputs.jump_state, in place in ``buf``); the flags the
        kernel takes. Vehicles whose time went backwards are skipped by the kernel, each on its own (as the numpy step
        does)."""
        dt = self.sp.dt_s
        with np.errstate(invalid="ignore"):
            gap = rec["t_s"] - buf["t_last_s"]
        known = np.isfinite(gap)
        backward = known & (gap < 0.5 * dt) & ~(gap < -self.sp.options.clock_reset_s)  # not a reset clock
        jump = known & (gap > 1.5 * dt) & ~backward  # (the kernel skips the backward ones itself)
        if jump.any():
            st = jump_state(self.unpack(buf), np.where(jump, gap - dt, 0.0), self.sp, cache, rec["raw"][..., I_OIL])
            buf["T_c"][..., : self.n], buf["pending_s"][..., : self.n_pub] = st.T_c, st.pending_s
        return np.ascontiguousarray(jump, dtype=np.int8).reshape(-1)

    def refresh_ttl(self, state: SensorState, job: TtlJob | None, cache: StepCache) -> SensorState:
        """The time-to-limit refresh a step left (the kernel's gvs_ttl_refresh; a job made by the numpy step: its
        points converted), into a new state."""
        if job is None:
            return state
        buf = self.pack(state)
        pts = job.raw if job.raw is not None else self._points(job)
        V = buf.shape[0] if buf.shape else None
        veh = self.vehicles(V)
        ttl = np.zeros(self.n_pub, dtype=self.S["real"])
        for v in job.vehicles:
            i = int(np.ravel_multi_index(v, pts.shape)) if v else 0
            self.lib.gvs_ttl_refresh(
                self._tables_p,
                veh.ctypes.data + (i if veh.shape[0] > 1 else 0) * veh.itemsize,
                pts.ctypes.data + i * pts.itemsize,
                ttl.ctypes.data,
            )
            buf["ttl_s"][v + (slice(0, self.n_pub),)] = ttl
        return self.unpack(buf)

    def _points(self, job: TtlJob) -> np.ndarray:
        """gvs_ttl_point records of a job's TtlPoint tuples (batch-shaped like its vehicles)."""
        shape = () if job.vehicles == ((),) else (max(v[0] for v in job.vehicles) + 1,)
        pts = np.zeros(shape, dtype=self.S["TtlPoint_dtype"])
        sizes = dict(
            T_main_c=self.n, src_w=self.ns, G_w_per_k=self.nl, G_streams_w_per_k=self.nst, T_bc_c=self.nb, used=N_INPUTS
        )
        for v, p in zip(job.vehicles, job.points):
            for k, size in sizes.items():
                pts[k][v][:size] = getattr(p, k)
            for k in ("dT_in_k", "Q_cool_w", "omega_in_rad_s", "T_oil_c", "rho_cp_j_per_m3k", "measured", "row"):
                pts[k][v] = getattr(p, k)
            pts["due"][v] = 1
        return pts

    def step_table(self, state: SensorState, raw: np.ndarray, t_s: np.ndarray, cache: StepCache, keep=None):
        """``(state, TableOutputs)``: one vehicle stepped through N rows of inputs (raw (N, 8) in INPUT_FIELDS
        order, t_s (N,) frame times or NaN), each time-to-limit refresh and time jump handled between kernel calls;
        ``keep`` (N,) bool: only those rows' outputs are converted and returned (None: every row's)."""
        N = raw.shape[0]
        m_max = max(1, min(N, TABLE_CHUNK))
        rec = np.empty(m_max, dtype=self.S["Inputs_dtype"])
        out = np.zeros(m_max, dtype=self.S["Outputs_dtype"])
        res = self._table_buffers(N if keep is None else int(np.count_nonzero(keep)), out.dtype, self.n_pub)
        filled = 0
        buf = self.pack(state)
        pt = np.zeros((), dtype=self.S["TtlPoint_dtype"])
        veh = self.vehicles(None).ctypes.data_as(C.POINTER(self.S["Vehicle"]))
        status = C.c_int(0)
        flags = None if keep is None else np.ascontiguousarray(keep, dtype=np.int8)
        for j0 in range(0, N, m_max):  # the same kernel steps, in chunks that reuse two buffers
            m = min(m_max, N - j0)
            rec["raw"][:m] = raw[j0 : j0 + m]
            rec["t_s"][:m] = t_s[j0 : j0 + m]
            kf = None if flags is None else flags[j0 : j0 + m]
            k = w = 0  # steps done, outputs written (the kept steps' only: the kernel writes no other)
            while k < m:
                done = self.lib.gvs_run(
                    self._tables_p,
                    veh,
                    buf.ctypes.data,
                    rec[k:].ctypes.data,
                    m - k,
                    0,
                    None if kf is None else kf[k:].ctypes.data,
                    out[w:].ctypes.data,
                    pt.ctypes.data,
                    C.byref(status),
                )
                w += done if kf is None else int(np.count_nonzero(kf[k : k + done]))
                k, w = self._after_run(buf, rec, out, pt, (k, w), done, status.value, cache, kf)
            self._fill_table(res, out[:w], filled)
            filled += w
        return self.unpack(buf), res

    def _after_run(self, buf, rec, out, pt, at, done: int, status: int, cache: StepCache, kf=None) -> tuple:
        """After a gvs_run of ``done`` rows from row j (``at`` = (j, outputs written)): a jump to propagate (its
        output written when ``kf``, the keep flags, keeps it), then a due refresh; the next row and outputs."""
        j, w = at
        if status < 0:
            raise CoreUnavailable(f"the C kernel refused its tables (code {status})")
        j += done
        if status == NEED_JUMP:
            gap = rec["t_s"][j] - float(buf["t_last_s"])
            st = jump_state(self.unpack(buf), gap - self.sp.dt_s, self.sp, cache, rec["raw"][j][I_OIL])
            buf["T_c"][:, : self.n], buf["pending_s"][: self.n_pub] = st.T_c, st.pending_s
            one = np.zeros((), dtype=self.S["TtlPoint_dtype"])
            kept = kf is None or bool(kf[j])
            self.lib.gvs_step(
                self._tables_p,
                self.vehicles(None).ctypes.data_as(C.POINTER(self.S["Vehicle"])),
                buf.ctypes.data,
                rec[j:].ctypes.data,
                1,
                (out[w:] if kept else np.zeros(1, dtype=out.dtype)).ctypes.data,
                one.ctypes.data,
            )
            pt[...] = one
            j += 1
            w += kept
        if pt["due"]:
            self.lib.gvs_ttl_refresh(
                self._tables_p, self.vehicles(None).ctypes.data, pt.ctypes.data, buf["ttl_s"].ctypes.data
            )
            pt["due"] = 0
        return j, w

    def run_batch(
        self,
        state: SensorState,
        raw: np.ndarray,
        keep: np.ndarray,
        nodes: np.ndarray,
        rec: np.ndarray,
        bc_shift_k: np.ndarray | None = None,
    ) -> np.ndarray:
        """V vehicles (per-vehicle effects as in ``self.sp``) stepped through the same inputs ``raw`` (n, 8) on the
        0.1 s grid, one kernel call per step and no time-to-limit refresh (the diagnosis needs only temperatures):
        ``rec[j]`` = the main copy's temperatures of ``nodes`` after step ``keep[j]`` (rec[0]: given).
        ``bc_shift_k`` (n, nb): added at each step to every vehicle's boundary temperatures (offline, boundaries
        measured on a rig; None: the defaults throughout; the ambient and coolant slots come from ``raw``)."""
        buf = self.pack(state)
        V = buf.shape[0]
        inp = np.empty((raw.shape[0], V), dtype=self.S["Inputs_dtype"])
        inp["raw"] = raw[:, None, :]
        inp["t_s"] = np.nan
        out = np.zeros(V, dtype=self.S["Outputs_dtype"])
        veh = self.vehicles(V)
        bc_at = set()
        if bc_shift_k is not None:  # on a copy: the cached records keep the defaults
            veh = veh.copy()
            bc_base_c = veh["T_bc_default_c"][:, : self.nb].copy()
            bc_at = boundary_change_steps(bc_shift_k)
        stride = 1 if veh.shape[0] > 1 else 0
        step_batch, tables, nbytes = self.lib.gvs_step_batch, self._tables_p, inp.strides[0]
        base, veh_p, buf_p, out_p = inp.ctypes.data, veh.ctypes.data, buf.ctypes.data, out.ctypes.data
        j = 1
        for k in range(raw.shape[0] - 1):
            if k in bc_at:  # new boundaries: the memoised bin conductances (radiation to them) computed again
                veh["T_bc_default_c"][:, : self.nb] = bc_base_c + bc_shift_k[k]
                buf["memo_valid"] = 0
            step_batch(tables, veh_p, stride, V, buf_p, base + k * nbytes, None, out_p, None, None)
            if j < keep.size and k + 1 == keep[j]:
                rec[j] = buf["T_c"][:, 0, nodes]
                j += 1
        return rec

    @staticmethod
    def _table_buffers(N: int, out_dtype: np.dtype, n_pub: int) -> TableOutputs:
        """Empty TableOutputs for N rows (the kernel's outputs converted: temperatures and times as float64)."""
        return TableOutputs(
            np.empty((N, n_pub)),
            np.empty((N, n_pub), dtype=out_dtype["level"].base),
            np.empty((N, n_pub)),
            np.empty(N, dtype=out_dtype["degraded_mode"]),
            np.empty((N, 4), dtype=bool),
            np.empty(N),
            np.empty(N),
            np.empty((N,) + out_dtype["rejects"].shape, dtype=out_dtype["rejects"].base),
            np.empty(N),
        )

    @staticmethod
    def _fill_table(res: TableOutputs, out: np.ndarray, j0: int) -> None:
        """Rows j0.. of ``res`` from the kernel's output records ``out``."""
        rows, pub = slice(j0, j0 + out.shape[0]), slice(0, res.T_c.shape[1])
        res.T_c[rows] = out["T_c"][:, pub]
        res.level[rows] = out["level"][:, pub]
        res.ttl_s[rows] = out["ttl_s"][:, pub]
        res.degraded_mode[rows] = out["degraded_mode"]
        for i, k in enumerate(("speed_valid", "torque_valid", "gear_valid", "oil_valid")):
            res.valid[rows, i] = out[k] != 0
        res.oil_innovation_c[rows] = out["oil_innovation_c"]
        res.model_oil_temp_c[rows] = out["model_oil_temp_c"]
        res.rejects[rows] = out["rejects"]
        res.oil_inlet_temp_c[rows] = out["oil_inlet_temp_c"]


__all__ = ["CompiledCore", "BufferedState", "TableOutputs"]
