"""The onboard virtual temperature sensor: parameters built and checked once, then the pure step.

    sensor = VirtualSensor(load_parameters("GRS905"))
    state = sensor.initial_state(T_oil_c=62.0)
    state, out = sensor.step(state, SensorInputs(1300.0, 2000.0, 9, 62.1, 20.0, 85.0, 40.0, 0.0))
    out.T_c, out.level, out.ttl_s, out.status.degraded_mode

The step itself is :func:`firmware_model.onboard.step.step` (``step(state, inputs, params, cache)``, pure, one
function for one truck, shape ``()``, and for a fleet, shape ``(V,)``); a :class:`VirtualSensor` holds its
:class:`~firmware_model.onboard.params.SensorParams` (``sp``) and its
:class:`~firmware_model.onboard.step_cache.StepCache` (``cache``). Module map (docs/sensor.md): records (inputs,
state, outputs, options), input_check, step, conductance_bins, held_modes (modal solution, first-crossing search),
held_inputs (linear system, time jumps, cool-down), time_to_limit, warning_levels (limits, levels), snapshot.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
from pathlib import Path

import numpy as np

from firmware_model.description import description_of
from firmware_model.errors import InputError, ParameterError
from firmware_model.onboard import reduce as R
from firmware_model.onboard.blas import limit_blas_threads
from firmware_model.onboard.core_select import select_core
from firmware_model.onboard.held_inputs import (
    cool_down,
    held_temperatures,
    jump_state,
    prepare_jump,
    shutdown_boundaries_c,
)
from firmware_model.onboard.kernel_interface import OIL_AGE_NONE_S
from firmware_model.onboard.params import SensorParams
from firmware_model.onboard.records import (
    I_AMB,
    I_GEAR,
    I_OIL,
    I_SPEED,
    I_TORQUE,
    INPUT_FIELDS,
    MAIN,
    N_INPUTS,
    N_REJECT,
    REJECT_REASONS,
    TWIN,
    SensorInputs,
    SensorOptions,
    SensorOutputs,
    SensorState,
    SensorStatus,
)
from firmware_model.onboard.snapshot import decode_snapshot, encode_snapshot, state_bytes
from firmware_model.onboard.step import step
from firmware_model.onboard.step_cache import StepCache
from firmware_model.onboard.time_to_limit import TtlJob
from firmware_model.onboard.warning_levels import Limits, load_limits
from firmware_model.parameters import Parameters
from firmware_model.physics.oil import check_temperature_c

__all__ = [
    "VirtualSensor",
    "SensorInputs",
    "SensorOutputs",
    "SensorState",
    "SensorStatus",
    "SensorOptions",
    "SensorParams",
    "StepCache",
    "INPUT_FIELDS",
    "REJECT_REASONS",
    "MAIN",
    "TWIN",
    "step",
]

#: sensor.held_step: "auto" (a held table steps at the largest step the stability proof allows that divides its row
#: period, firmware_model.onboard.stability.held_step_s) or "reference" (every 0.1 s, as a vehicle)
HELD_STEPS = ("auto", "reference")


class VirtualSensor:
    """The onboard sensor: parameters built and checked once, then the pure step.

    ``params``: a validated gearbox :class:`~firmware_model.parameters.Parameters`; ``limits``: a :class:`Limits`,
    the path of a limits TOML, or None (config [sensor] limits, else params/limits.toml); ``config``: a
    :class:`~firmware_model.config.Config` (its [sensor] section: oil_mode, limits, debounce_s, hysteresis_c);
    ``effects``: {effect id: value or per-vehicle array} for the effects in firmware_model.onboard.reduce.EFFECT_HOOKS
    (and oil_level_low, scalar); ``partition``: "fine" (default) or "compact"; ``core``: "auto" (default: the
    compiled C kernel when it loads, else the numpy step), "c" (the kernel or an error saying why) or "numpy" (the
    readable reference); ``options``: SensorOptions overrides. Raises StabilityError when the parameter set is
    unsafe for the 0.1 s explicit step. ``core`` is the core that steps (firmware_model.onboard.core_select: a
    NumpyCore or a CompiledCore, the same methods); ``core_name`` says which and, for "auto", why not the kernel.
    """

    Inputs = SensorInputs
    Status = SensorStatus
    Outputs = SensorOutputs
    #: names of the reject counters (SensorStatus.rejects), in order
    reject_reasons = REJECT_REASONS
    input_fields = INPUT_FIELDS

    def __init__(
        self,
        params: Parameters,
        limits=None,
        config=None,
        effects: dict | None = None,
        partition: str | dict = "fine",
        core: str = "auto",
        **options,
    ):
        limit_blas_threads()  # firmware_model.onboard.blas: one BLAS thread (the small eigh is 25x slower with more)
        sensor_cfg = dict(getattr(config, "sensor", None) or {}) if config is not None else {}
        d = description_of(params)
        published = R.published_components(d)
        # the limits: the caller's, else the configuration's [sensor] limits, else the description's own file
        if limits is None and sensor_cfg.get("limits") is None:
            limits = d.limits_path
        lim = limits if isinstance(limits, Limits) else _limits_of(limits, config, sensor_cfg, published)
        oil_mode = options.pop("oil_mode", sensor_cfg.get("oil_mode", "measured"))
        if oil_mode not in ("measured", "model"):
            raise ParameterError(f"sensor.oil_mode = {oil_mode!r} must be 'measured' or 'model'")
        held_step = options.pop("held_step", sensor_cfg.get("held_step", "auto"))
        if held_step not in HELD_STEPS:
            raise ParameterError(f"sensor.held_step = {held_step!r} must be one of {', '.join(map(repr, HELD_STEPS))}")
        if options.get("ttl_sump", "model") not in ("model", "held"):
            raise ParameterError(f"sensor option ttl_sump = {options['ttl_sump']!r} must be 'model' or 'held'")
        if "ttl_method" in sensor_cfg:  # the configuration's choice, unless the caller's options name one
            options.setdefault("ttl_method", sensor_cfg["ttl_method"])
        if options.get("ttl_method", "bound") not in ("march", "bound"):
            raise ParameterError(f"sensor.ttl_method = {options['ttl_method']!r} must be 'march' or 'bound'")
        reset_s = options.get("clock_reset_s", 10.0)
        if not (isinstance(reset_s, (int, float)) and 1.0 <= reset_s < math.inf):
            raise ParameterError(
                f"sensor option clock_reset_s = {reset_s!r} must be a number of seconds, at least 1 "
                f"(time back by more than it is a reset clock; less is skipped)"
            )
        period_s = options.get("oil_period_s", 0.0)
        if not (isinstance(period_s, (int, float)) and 0.0 <= period_s < math.inf):
            raise ParameterError(f"sensor option oil_period_s = {period_s!r} must be a number of seconds, 0 or more")
        #: a rig's configuration: the sump is conditioned from outside, the model's own sump (the twin) means nothing
        self.rig = params.strings.get("cooler.kind") in ("hold", "measured")
        if self.rig:
            # a rig: the sump is conditioned from outside (no cooler to model, a constant reading is normal, and
            # the time to limit holds the measured sump where it is: the twin's, with no cooler, climbs without end)
            params = params.with_cooler_kind("none")
            options.setdefault("oil_frozen_s", math.inf)
            options.setdefault("ttl_sump", "held")
        try:
            opts = SensorOptions(oil_mode=oil_mode, **options)
        except TypeError as exc:
            raise ParameterError(f"unknown sensor option: {exc}") from None
        if opts.initial_temp_c is not None:
            check_temperature_c("sensor option initial_temp_c", opts.initial_temp_c)
        self.params = params
        self.reduced = R.build_reduced(params, partition=partition, effects=effects)
        self.effects = R.make_effects({k: v for k, v in (effects or {}).items() if k in R.EFFECT_HOOKS}, self.reduced)
        self.sp = SensorParams.build(self.reduced, lim, self.effects, opts)
        self.cache = StepCache()
        self.limits = lim
        self.options = opts
        self.held_step = held_step
        self.core = select_core(core, self.sp)
        self._core_choice = core
        self._stepped: dict = {}

    @property
    def dt_s(self) -> float:
        """The explicit step [s]: components.STEP_S (0.1 s), or a held replay's coarser one (:meth:`with_step`)."""
        return self.sp.dt_s

    def with_step(self, dt_s: float, ttl_period_s: float | None = None) -> VirtualSensor:
        """This sensor (parameters, limits, effects, options, core choice) at another explicit step ``dt_s`` (a held
        replay's, firmware_model.onboard.stability.held_step_s), the stability proof checked again at it
        (StabilityError beyond it); ``ttl_period_s``: the time-to-limit period there (None: this sensor's). Built
        once per (step, period) and kept. Only offline: the CAN service refuses a step other than 0.1 s."""
        period_s = self.options.ttl_period_s if ttl_period_s is None else float(ttl_period_s)
        if dt_s == self.dt_s and period_s == self.options.ttl_period_s:
            return self
        key = (float(dt_s), period_s)
        if key not in self._stepped:
            other = copy.copy(self)
            other.reduced = R.with_step(self.reduced, float(dt_s))
            # one step without speed or torque is still "held" at any step (a 15 s step: not "not available"
            # at once); at 0.1-10 s the hold is the options' own
            hold_s = max(self.options.hold_s, float(dt_s))
            other.options = dataclasses.replace(self.options, ttl_period_s=period_s, hold_s=hold_s)
            other.sp = SensorParams.build(other.reduced, self.limits, self.effects, other.options)
            other.cache = StepCache()
            other.core = select_core(self._core_choice, other.sp)
            other._stepped = {}
            self._stepped[key] = other
        return self._stepped[key]

    @property
    def core_name(self) -> str:
        """One line naming the core that steps (and, for core="auto" on numpy, why not the kernel)."""
        return self.core.name

    @property
    def compiled(self):
        """The CompiledCore when the kernel steps, else None (read-only; :attr:`core` is the core either way)."""
        return self.core if self.core.compiled else None

    # -- state

    @property
    def nodes(self) -> tuple:
        return self.reduced.nodes

    @property
    def published(self) -> tuple:
        """The published components' ids (the description's published.order): the last axis of the outputs'
        temperatures, levels and times to limit, and of the state's level, pending_s and ttl_s."""
        return self.reduced.published

    @property
    def n_pub(self) -> int:
        return len(self.reduced.published)

    @property
    def oil_inlet(self) -> bool:
        """True for a forced oil system: the status's ``oil_inlet_temp_c`` is its oil inlet (else NaN)."""
        return bool(self.reduced.oil_inlet)

    def initial_state(
        self,
        T_oil_c=None,
        snapshot=None,
        elapsed_s: float = 0.0,
        n_vehicles: int | None = None,
        ambient_c: float | None = None,
        running_s: float = 0.0,
    ) -> SensorState:
        """Start: every node at the measured oil temperature (NaN/None, or a reading outside the oil input's plausible
        range, which the step rejects too: ``options.initial_temp_c``, else ``ambient_c``, the first ambient reading,
        when it lies in the ambient input's plausible range, else the parameters' ambient boundary), or from a
        snapshot (a SensorState, or the bytes/str/dict of :meth:`snapshot`) cooled down for
        ``elapsed_s`` with the engine off. ``running_s``: the first seconds of that time during which the engine
        ran on with the snapshot's inputs held (a gateway that died while the truck drove: its last state was saved
        while stepping, not at a clean stop), at most ``options.time_jump_hold_s``, as for a forward time jump;
        then the engine is off. With both a snapshot and a measured oil: the measurement wins when the
        cooled snapshot's sump is more than 10 K off (then every node starts at it), else it replaces the sump."""
        if snapshot is not None:
            return self._restored_state(
                decode_snapshot(snapshot, self.reduced), T_oil_c, elapsed_s, ambient_c, running_s
            )
        rp = self.reduced
        B = () if n_vehicles is None else (int(n_vehicles),)
        T0 = self._plausible_oil_c(T_oil_c)
        default = self.options.initial_temp_c
        if default is None:  # the ambient reading (per vehicle) where plausible (NaN is not)
            amb = np.asarray(np.nan if ambient_c is None else ambient_c, dtype=float)
            default = np.where(
                (amb >= self.sp.input_lo[I_AMB]) & (amb <= self.sp.input_hi[I_AMB]),
                amb,
                float(rp.bc_default_c[rp.i_ambient]),
            )
        read = np.broadcast_to(np.isfinite(T0), B)
        T0 = np.broadcast_to(np.where(np.isfinite(T0), T0, default), B).astype(float)
        hold = np.full(B + (N_INPUTS,), np.nan)
        hold[..., [I_SPEED, I_TORQUE, I_GEAR]] = 0.0
        hold[..., I_OIL] = T0
        age_s = np.zeros(B + (N_INPUTS,))
        age_s[..., I_OIL] = np.where(read, 0.0, OIL_AGE_NONE_S)  # no reading yet: the first one is not judged
        return SensorState(
            T_c=np.broadcast_to(T0[..., None, None], B + (2, rp.n)).copy(),
            lag_w=np.zeros(B + (len(rp.src_names),)),
            hold=hold,
            age_s=age_s,
            same_s=np.zeros(B + (N_INPUTS,)),
            raw_prev=np.full(B + (N_INPUTS,), np.nan),
            oil_ref_c=np.array(T0, dtype=float),
            level=np.zeros(B + (self.n_pub,), dtype=np.int8),
            pending_s=np.zeros(B + (self.n_pub,)),
            ttl_s=np.full(B + (self.n_pub,), np.nan),
            t_last_s=np.full(B, np.nan),
            k=np.zeros(B, dtype=np.int64),
            rejects=np.zeros(B + (N_REJECT,), dtype=np.int64),
            recover_s=np.zeros(B),
        )

    def _plausible_oil_c(self, T_oil_c) -> np.ndarray:
        """An oil reading to start from as an array, NaN where absent or outside the oil input's plausible range (a
        start at 1e308 or below absolute zero would put every node there)."""
        T = np.asarray(np.nan if T_oil_c is None else T_oil_c, dtype=float)
        return np.where((T >= self.sp.input_lo[I_OIL]) & (T <= self.sp.input_hi[I_OIL]), T, np.nan)

    def _restored_state(self, st: SensorState, T_oil_c, elapsed_s: float, ambient_c, running_s: float = 0.0):
        """A restored snapshot propagated over ``elapsed_s`` (its inputs held for ``running_s``, capped, then engine
        off), the measured oil applied (see :meth:`initial_state`)."""
        rp = self.reduced
        amb = ambient_c
        if amb is None:
            a = np.asarray(st.hold[..., I_AMB], dtype=float)
            amb = float(a.reshape(-1)[0]) if np.all(np.isfinite(a)) else float(rp.bc_default_c[rp.i_ambient])
        T = np.array(st.T_c, dtype=float, copy=True)
        if elapsed_s and elapsed_s > 0:
            held_s = (
                min(float(running_s), self.sp.options.time_jump_hold_s, float(elapsed_s))
                if running_s and running_s > 0
                else 0.0
            )
            for v in np.ndindex(T.shape[:-2]):
                if held_s > 0:
                    T[v] = held_temperatures(st, v, held_s, self.sp)
                bc = shutdown_boundaries_c(self.sp, np.asarray(st.hold[v], dtype=float))
                bc[rp.i_ambient] = amb
                for c in (MAIN, TWIN):
                    T[v + (c,)] = cool_down(self.sp, self.cache, T[v + (c,)], float(elapsed_s) - held_s, amb, bc)
        T, level, pending_s, age_s = self._restored_oil(st, T, T_oil_c, elapsed_s)
        B = T.shape[:-2]
        return st._replace(
            T_c=T,
            level=level,
            pending_s=pending_s,
            t_last_s=np.full(B, np.nan),
            age_s=age_s,
            ttl_s=np.full(B + (self.n_pub,), np.nan),
            k=np.zeros(B, dtype=np.int64),
        )

    def _restored_oil(self, st: SensorState, T, T_oil_c, elapsed_s: float):
        """The oil reading of a restore on the propagated temperatures ``T``: (T, level, pending_s, age_s). A
        plausible reading more than 10 K off the sump restarts every node at it (the saved warning levels go with
        the saved temperatures: else a warning is kept for the debounce time on a gearbox restarted at 40 degC),
        else the sump takes it; one within ``oil_step_c`` of a reading rejected before the stop goes on being judged
        by the step check instead. Without a reading, and unless a reading was being rejected before the stop, the
        saved sump counts as never read (the first reading is taken as it comes)."""
        rp, B = self.reduced, T.shape[:-2]
        meas = np.broadcast_to(self._plausible_oil_c(T_oil_c), B)
        prev_age = np.asarray(st.age_s, dtype=float)[..., I_OIL]
        prev_raw = np.asarray(st.raw_prev, dtype=float)[..., I_OIL]
        rejected = (prev_age > 0.0) & np.isfinite(prev_raw)  # a reading came and was not taken
        read = np.isfinite(meas) & ~(rejected & (np.abs(meas - prev_raw) <= self.sp.options.oil_step_c))
        off = read & (np.abs(T[..., MAIN, rp.i_oil] - meas) > 10.0)
        T = np.where(off[..., None, None], meas[..., None, None], T)
        T[..., :, rp.i_oil] = np.where(read[..., None], meas[..., None], T[..., :, rp.i_oil])
        level = np.where(off[..., None], 0, st.level).astype(np.asarray(st.level).dtype)
        pending_s = np.where(off[..., None], 0.0, st.pending_s)
        age_s = np.array(np.where(elapsed_s > 0, np.maximum(st.age_s, elapsed_s), st.age_s), dtype=float)
        age_s[..., I_OIL] = np.where(read | rejected, age_s[..., I_OIL], OIL_AGE_NONE_S)
        return T, level, pending_s, age_s

    # -- the step

    def step(self, state: SensorState, inputs: SensorInputs):
        """``(state, outputs)``: one step (:func:`firmware_model.onboard.step.step`, or the compiled kernel) with
        this sensor's parameters and cache."""
        return self.core.step(state, inputs, self.cache)

    def step_deferred(self, state: SensorState, inputs: SensorInputs):
        """``(state, outputs, job)``: the step without the time-to-limit refresh; call :meth:`refresh_ttl` before
        the next step (same outputs as :meth:`step`, bit for bit)."""
        return self.core.step_deferred(state, inputs, self.cache)

    def refresh_ttl(self, state: SensorState, job: TtlJob | None) -> SensorState:
        """The time-to-limit refresh a :meth:`step_deferred` left (None: nothing due)."""
        return self.core.refresh_ttl(state, job, self.cache)

    def prepare_jump(self, state: SensorState, t_s: float) -> bool:
        """Do now the propagation over the forward time jump that a step at run time ``t_s`` would see (one vehicle;
        held_inputs.prepare_jump), so that the step itself is quick: the live service calls it when the first frame
        after a gap arrives, a step period before the step that publishes. That step's outputs are the same bits
        with or without it. True when a jump was propagated."""
        t_last_s = np.asarray(state.t_last_s, dtype=float)
        if t_last_s.shape:
            return False
        gap_s = float(t_s) - float(t_last_s)
        if not (math.isfinite(gap_s) and gap_s > 1.5 * self.sp.dt_s):  # the step's own test of a forward jump
            return False
        prepare_jump(state, gap_s - self.sp.dt_s, self.sp, self.cache)
        return True

    def step_table(self, state: SensorState, raw, t_s=None, keep=None):
        """``(state, TableOutputs)``: one vehicle stepped through a table of inputs: ``raw`` (N, 8) in INPUT_FIELDS
        order (NaN missing), ``t_s`` (N,) frame times (None or NaN: the 0.1 s grid). The compiled core runs the
        table in one call (the time to limit refreshed inside; forward time jumps between calls); the numpy core
        steps row by row (same outputs). ``keep`` (N,) bool: the outputs of those rows only (a held replay keeps
        one step per row: converting every step's outputs cost a quarter of its time)."""
        raw = np.ascontiguousarray(raw, dtype=float)
        if raw.ndim == 1 and raw.size == N_INPUTS:
            raw = raw.reshape(1, N_INPUTS)
        if raw.ndim != 2 or raw.shape[1] != N_INPUTS:
            raise InputError(
                f"a table of inputs has {N_INPUTS} columns ({', '.join(INPUT_FIELDS)}), not shape {raw.shape}"
            )
        t = np.full(raw.shape[0], np.nan) if t_s is None else np.asarray(t_s, dtype=float).reshape(-1)
        if t.shape[0] == 1 and raw.shape[0] != 1:
            t = np.full(raw.shape[0], t[0])
        if t.shape[0] != raw.shape[0]:
            raise InputError(f"t_s has {t.shape[0]} frame times for {raw.shape[0]} rows of inputs")
        if keep is not None:
            keep = np.asarray(keep, dtype=bool).reshape(-1)
            if keep.shape[0] != raw.shape[0]:
                raise InputError(f"keep has {keep.shape[0]} flags for {raw.shape[0]} rows of inputs")
        return self.core.step_table(state, raw, t, self.cache, keep)

    def step_tables(self, jobs, workers: int | None = None):
        """Many vehicles' tables: ``jobs`` an iterable of ``(state, raw)`` or ``(state, raw, t_s)`` (as
        :meth:`step_table`); yields ``(state, TableOutputs)`` per job, in order. With the compiled core the tables
        run on ``workers`` threads (default: the CPU count; the kernel call releases the GIL and shares only the
        read-only tables: ``core.parallel_tables``), at most two per thread in flight, so a fleet's outputs never all
        sit in memory at once; the numpy core runs them one after the other."""
        if workers is not None and not (isinstance(workers, int) and workers >= 1):
            raise InputError(f"workers is a number of threads >= 1 (or None: the CPU count), not {workers!r}")
        jobs = (_table_job(job) for job in jobs)
        if not self.core.parallel_tables or workers == 1:
            for job in jobs:
                yield self.step_table(*job)
            return
        from collections import deque
        from concurrent.futures import ThreadPoolExecutor

        n_workers = max(1, int(workers or os.cpu_count() or 1))
        with ThreadPoolExecutor(n_workers, thread_name_prefix="gvs-table") as pool:
            window: deque = deque()
            for job in jobs:
                window.append(pool.submit(self.step_table, *job))
                if len(window) >= 2 * n_workers:
                    yield window.popleft().result()
            while window:
                yield window.popleft().result()

    def cool_down(self, T0_c, elapsed_s: float, ambient_c: float, boundaries_c=None):
        """Node temperatures of one network copy after ``elapsed_s`` with the engine off (held_inputs.cool_down)."""
        return cool_down(self.sp, self.cache, T0_c, elapsed_s, ambient_c, boundaries_c)

    def warm_up(self) -> None:
        """Run, and discard, one time-jump propagation of the initial state (held inputs, then engine off), so that
        the first time jump on the bus does not also pay for first use (numpy's and LAPACK's code paths, the
        engine-off modes of the default ambient): about 3 ms instead of 1.3 ms natively, and under emulation the
        difference is tens of milliseconds of the resume latency. Changes no state and no output."""
        st = self.initial_state()
        jump_state(st, self.sp.options.time_jump_hold_s + 60.0, self.sp, self.cache)

    # -- snapshots and figures

    def snapshot(self, state: SensorState) -> bytes:
        """Serialise a state (JSON, UTF-8): restorable with ``initial_state(snapshot=...)``, also across processes."""
        return encode_snapshot(state, self.reduced)

    def state_bytes(self, dtype=np.float32) -> int:
        """Bytes of one vehicle's state as an ECU would hold it (floats as ``dtype``, levels 1 byte, counters and
        the step count 4 bytes)."""
        return state_bytes(self.initial_state(T_oil_c=40.0), dtype)


def _table_job(job) -> tuple:
    """A step_tables job as step_table's arguments, or a one-sentence InputError."""
    if not isinstance(job, (tuple, list)) or len(job) not in (2, 3):
        raise InputError(
            f"a step_tables job is (state, raw) or (state, raw, t_s), not {type(job).__name__} "
            f"of length {len(job) if hasattr(job, '__len__') else '?'}"
        )
    return tuple(job)


def _limits_of(path, config, sensor_cfg: dict, published: tuple) -> Limits:
    """Limits from ``path`` (None: config [sensor] limits, else the default file); a relative path in a config file
    is taken relative to that file when it exists there."""
    path = path if path is not None else sensor_cfg.get("limits")
    if (
        path is not None
        and config is not None
        and not str(path).startswith("/")
        and getattr(config, "origin", "defaults") not in ("defaults", "")
    ):
        cand = Path(config.origin).parent / path
        path = cand if cand.exists() else path
    return load_limits(path, sensor_cfg.get("debounce_s"), sensor_cfg.get("hysteresis_c"), published=published)
