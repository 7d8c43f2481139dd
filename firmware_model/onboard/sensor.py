"""The onboard virtual temperature sensor: a pure fixed-step core over the onboard network (firmware_model.onboard.reduce).

    sensor = VirtualSensor(load_parameters("GRS905"))
    state = sensor.initial_state(T_oil_c=62.0)
    state, out = sensor.step(state, SensorInputs(1300.0, 2000.0, 9, 62.1, 20.0, 85.0, 40.0, 0.0))
    out.T_c, out.level, out.ttl_s, out.status.degraded_mode

``step(state, inputs, params) -> (state, outputs)`` is pure: no I/O, no clock, nothing that grows; every array has
a fixed shape. The same function serves the live CAN service, offline replay and a fleet batch: give it a state of
shape ``(n_vehicles, ...)`` (``initial_state(..., n_vehicles=V)``) and input fields that are arrays of shape (V,).
Step: dt = 0.1 s, forward Euler (stability proven when the parameters load, see firmware_model.onboard.reduce).

Per step (docs/sensor.md):

1. inputs are checked and repaired (table "Bad input"): hold last good, clamp, or degrade; every rejection counted;
2. the operating point: gear, input speed and torque, and the oil temperature: the measured one when it is valid
   (a boundary condition of the network, as in the seed's "measured" mode), else the network's own sump;
3. heat of every loss source (compact loss maps), through the seed's first-order heat lag (tau 1 s, exact for a
   held input: the step's average of the lagged heat);
4. conductances of every link at the operating point (compact laws), the cooler (seed 3.4, Eq 82-83) and the
   oil-system inlet drop it causes;
5. one Euler step of two copies of the network side by side: the *main* copy (oil measured when available) whose
   temperatures are published, and the *open-loop twin* whose sump is always integrated with the cooler model;
   ``measured - twin sump`` is the published oil innovation, the live view of the sim-to-real gap;
6. warning levels (two levels, hysteresis, debounce), with the time to limit of the last refresh counted down;
7. every ``ttl_period_s``, the refresh of the time to limit from the new state with the inputs held (exact modal
   solution of the frozen linear network, firmware_model.onboard.overheat): :func:`refresh_ttl`, which :func:`step` runs at
   its end and the CAN service runs after sending the step's frames (:func:`step_deferred`); same outputs either way.
"""
from __future__ import annotations

import base64
import json
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from firmware_model.onboard import reduce as R
from firmware_model.onboard.blas import limit_blas_threads
from firmware_model.components import PUBLISHED
from firmware_model.errors import InputError, ParameterError
from firmware_model.physics.kinematics import GEAR_MAX, GEAR_MIN
from firmware_model.network import BOUNDARIES
from firmware_model.onboard.overheat import LEVEL_NA, HeldInputSolver, Limits, load_limits, update_levels
from firmware_model.parameters import Parameters

N_PUB = len(PUBLISHED)
#: input fields in the order of the state's hold / age arrays
INPUT_FIELDS = ("speed_rpm", "torque_nm", "gear", "oil_temp_c", "ambient_temp_c", "coolant_temp_c",
                "vehicle_speed_kmh", "retarder_torque_nm")
I_SPEED, I_TORQUE, I_GEAR, I_OIL, I_AMB, I_COOL, I_VKMH, I_RET = range(8)
#: why inputs were rejected or repaired (columns of the reject counters)
REJECT_REASONS = ("speed_missing", "speed_clamped", "torque_missing", "torque_clamped", "gear_missing",
                  "gear_unknown", "oil_missing", "oil_implausible", "oil_frozen", "drive_frozen", "aux_missing",
                  "time_jump", "time_backward")
NR = len(REJECT_REASONS)
RJ = {k: i for i, k in enumerate(REJECT_REASONS)}
#: DegradedMode (docs/can.md): 0 normal, 1 oil model only, 2 inputs missing - holding, 3 not initialised
MODE_NORMAL, MODE_OIL_MODEL, MODE_HOLDING, MODE_NOT_INITIALISED = 0, 1, 2, 3
MAIN, TWIN = 0, 1
SNAPSHOT_SCHEMA = "vsensor-snapshot/1"


class SensorInputs(NamedTuple):
    """One step's inputs; NaN means not available / stale. Fields may be arrays (one value per vehicle)."""
    speed_rpm: float = math.nan
    torque_nm: float = math.nan
    gear: float = math.nan
    oil_temp_c: float = math.nan
    ambient_temp_c: float = math.nan
    coolant_temp_c: float = math.nan
    vehicle_speed_kmh: float = math.nan
    retarder_torque_nm: float = math.nan
    #: optional frame time of this step [s] (time-jump detection); NaN: the caller keeps the 0.1 s grid
    t_s: float = math.nan


class SensorState(NamedTuple):
    """Everything the sensor remembers; fixed shapes (batch shape B = () or (V,))."""
    T_c: np.ndarray          # B + (2, n): node temperatures of the main copy and the open-loop twin [degC]
    lag_w: np.ndarray        # B + (ns,): heat-lag state of every loss source [W]
    hold: np.ndarray         # B + (8,): last good value of every input (INPUT_FIELDS)
    age_s: np.ndarray        # B + (8,): time since each input was last good [s]
    same_s: np.ndarray       # B + (8,): time each raw input has been bit-identical [s]
    raw_prev: np.ndarray     # B + (8,): previous raw input values
    oil_ref_c: np.ndarray    # B: twin sump temperature when the measured oil last changed [degC]
    level: np.ndarray        # B + (28,): warning levels (int8)
    pending_s: np.ndarray    # B + (28,): debounce timers [s]
    ttl_s: np.ndarray        # B + (28,): last time to limit [s]
    t_last_s: np.ndarray     # B: frame time of the last step (NaN unknown)
    k: np.ndarray            # B: steps done (int64)
    rejects: np.ndarray      # B + (NR,): reject counters (int64)


class SensorStatus(NamedTuple):
    degraded_mode: np.ndarray    # 0 normal, 1 oil model only, 2 inputs missing - holding
    speed_valid: np.ndarray
    torque_valid: np.ndarray
    gear_valid: np.ndarray
    oil_valid: np.ndarray
    valid_flags: np.ndarray      # bit i: INPUT_FIELDS[i] was valid this step
    model_oil_temp_c: np.ndarray  # the open-loop twin's sump [degC]
    oil_innovation_c: np.ndarray  # measured - model oil (NaN without a valid measurement) [K]
    oil_source: np.ndarray       # 0 measured, 1 modelled (the main network's sump)
    frozen_flags: np.ndarray     # bit i: INPUT_FIELDS[i] frozen (bit-identical too long)
    rejects: np.ndarray          # cumulative counters, REJECT_REASONS order


class SensorOutputs(NamedTuple):
    T_c: np.ndarray      # (..., 28) published temperatures [degC], PUBLISHED order; always finite
    level: np.ndarray    # (..., 28) 0 normal, 1 warning, 2 critical, 3 not available (int8)
    ttl_s: np.ndarray    # (..., 28) time to the warning limit with held inputs [s]: inf never, NaN not available
    status: SensorStatus


@dataclass(frozen=True)
class SensorOptions:
    """Behaviour settings (docs/sensor.md, "Bad input"); all times in seconds."""
    oil_mode: str = "measured"           # measured: use a valid measurement; model: always the modelled sump
    hold_s: float = 10.0                 # drive inputs missing longer than this: levels "not available"
    drive_frozen_s: float = 120.0        # speed and torque bit-identical this long while turning: flagged frozen
    oil_frozen_s: float = 300.0          # measured oil bit-identical this long ...
    oil_frozen_drift_c: float = 3.0      # ... while the twin's sump moved this much: measurement frozen
    oil_step_c: float = 5.0              # a measured oil step larger than this within one step is implausible
    oil_range_c: tuple = (-40.0, 200.0)  # plausible measured oil
    aux_range_c: tuple = (-60.0, 150.0)  # plausible ambient / coolant
    max_vehicle_speed_kmh: float = 250.0
    default_vehicle_speed_kmh: float = 50.0
    ttl_period_s: float = 1.0            # time to limit refreshed this often (0: every step)
    ttl_sump: str = "model"              # time to limit: the sump evolves with the cooler model ("model") or a
    #                                      measured reading is held like the other inputs ("held")
    time_jump_hold_s: float = 60.0       # forward jumps: held inputs this long, then engine off
    initial_temp_c: float | None = None  # cold start without oil: default = ambient boundary


@dataclass(frozen=True)
class SensorParams:
    """Frozen record of everything the pure step needs."""
    reduced: R.ReducedParams
    limits: Limits
    effects: R.Effects
    options: SensorOptions
    solver: HeldInputSolver = field(compare=False, repr=False, default=None)
    #: memo of the quantised conductances (a bounded cache of a pure function)
    kcache: dict = field(compare=False, repr=False, default_factory=dict)

    @property
    def dt_s(self) -> float:
        return self.reduced.dt_s

    def __post_init__(self):
        rp, eff, opt = self.reduced, self.effects, self.options
        tau, dt = rp.heat_lag_tau_s, rp.dt_s
        d = object.__setattr__
        d(self, "a_lag", -math.expm1(-dt / tau) if tau > 0 else 1.0)
        d(self, "lag_ratio", tau / dt if tau > 0 else 0.0)
        d(self, "dt_inv_C", dt / np.asarray(rp.C_j_per_k, dtype=float))
        bc = np.array(rp.bc_default_c, dtype=float)
        bc[rp.i_hot] = bc[rp.i_hot] + np.asarray(eff.hot_offset_c).reshape(-1)[0] if np.ndim(eff.hot_offset_c) == 0 \
            else bc[rp.i_hot]
        d(self, "bc", bc if np.ndim(eff.hot_offset_c) == 0 else
          np.broadcast_to(rp.bc_default_c, np.shape(eff.hot_offset_c) + bc.shape) + np.eye(len(bc))[rp.i_hot]
          * np.asarray(eff.hot_offset_c)[..., None])
        d(self, "aux_default", np.array([rp.bc_default_c[rp.i_ambient], rp.bc_default_c[rp.i_coolant],
                                         opt.default_vehicle_speed_kmh, 0.0]))
        d(self, "cooler_scale", np.asarray(eff.cooler_scale)[..., None] if np.ndim(eff.cooler_scale)
          else float(eff.cooler_scale))
        d(self, "thermostat_offset", np.asarray(eff.thermostat_offset_c)[..., None]
          if np.ndim(eff.thermostat_offset_c) else float(eff.thermostat_offset_c))
        d(self, "ttl_every", max(int(round(opt.ttl_period_s / dt)), 1))
        d(self, "scalar_effects", all(np.ndim(v) == 0 for v in (
            eff.teeth_oil_h, eff.planet_oil_h, eff.housing_air_h, eff.cooler_scale, eff.thermostat_offset_c,
            eff.hot_offset_c, eff.retarder_frac, eff.churn_scale, eff.needle_scale)) and np.ndim(eff.src_scale) <= 1)


# ---------------------------------------------------------------------------------------------------------------
# the pure step


def _raw_inputs(inputs, B):
    if B == ():
        try:
            return np.array(inputs[:8], dtype=float)
        except (TypeError, ValueError):
            pass
    return np.stack([np.broadcast_to(np.asarray(inputs[i], dtype=float), B) for i in range(8)], axis=-1)


#: operating-point quantisation of the conductances (docs/sensor.md): 1 % in speed, 0.5 K in oil temperature
SPEED_BIN_REL = 0.01
SPEED_BIN_MIN_RAD_S = 1.0          # below ~10 rpm the conductances are evaluated at 0
OIL_BIN_C = 0.5
#: the step clips the oil-system inlet drop (sump minus cooler outlet) to +- this [K]
INLET_DROP_MAX_K = 30.0
_LN_BIN = math.log1p(SPEED_BIN_REL)


def quantise(w_in, T_oil_c):
    """Bin centres of the operating point at which the conductances are evaluated: the conductances are then a pure
    function of (gear, speed bin, oil bin), cached per bin for one vehicle and recomputed for a batch (same values)."""
    w = np.asarray(w_in, dtype=float)
    b = np.round(np.log(np.maximum(w, SPEED_BIN_MIN_RAD_S)) / _LN_BIN)
    w_q = np.where(w >= SPEED_BIN_MIN_RAD_S, np.exp(b * _LN_BIN), 0.0)
    T_q = np.round(np.asarray(T_oil_c, dtype=float) / OIL_BIN_C) * OIL_BIN_C
    return w_q, T_q, b


def _radiation_at(sp: SensorParams, T_q, h):
    """Radiation conductances (Eq 81) linearised with the housings at the bin's oil temperature: the housings sit
    within a few kelvin of the sump (200 W/(m2 K) on 1.7 m2), which moves h_rad by ~1 %."""
    rp = sp.reduced
    T1 = np.minimum(np.maximum(np.asarray(T_q, dtype=float), R.RAD_T_RANGE_C[0]), R.RAD_T_RANGE_C[1])[..., None] \
        + R.ht.KELVIN_OFFSET
    T2 = np.take(np.asarray(sp.bc, dtype=float), h.rad_bc, axis=-1) + R.ht.KELVIN_OFFSET
    return rp.rad_area_eps * _SIGMA * (T1 * T1 + T2 * T2) * (T1 + T2)


def _conductances_q(sp: SensorParams, row, w_in, T_oil, h):
    """(G, stream G) at the quantised operating point (radiation at the bin's oil temperature); the batch path."""
    rp = sp.reduced
    w_q, T_q, b = quantise(w_in, T_oil)
    x, prop, phi = R.oil_row(rp, T_q, h)
    G, Gs = R.conductances(rp, row, w_q, x, prop, phi, None, None, sp.effects, h, radiation=False)
    if rp.rad_link.size:
        G[..., rp.rad_link] = _radiation_at(sp, T_q, h)
    return G, Gs


def step(state: SensorState, inputs: SensorInputs, sp: SensorParams):
    """One 0.1 s step. Pure: returns the new state and the outputs; the input state is not modified.

    One vehicle (scalar state) runs :func:`step_scalar`, the same arithmetic written for scalars (what an ECU would
    run); a batch runs :func:`step_vector`. Tests hold the two equal. Equivalent to :func:`step_deferred` followed
    by :func:`refresh_ttl`."""
    state, outputs, job = step_deferred(state, inputs, sp)
    return refresh_ttl(state, job), outputs


def step_deferred(state: SensorState, inputs: SensorInputs, sp: SensorParams):
    """:func:`step` without its slow part: ``(state, outputs, job)``; ``refresh_ttl(state, job)`` must run before
    the next step (the CAN service runs it after the step's frames are on the bus, off the latency path).

    The time to limit is refreshed every ``ttl_period_s`` from the state *after* a step and published (counted down)
    from the next step on; the outputs of a step never depend on that step's refresh, so deferring it changes when
    the work is done, not a single output bit."""
    if state.t_last_s.ndim == 0 and sp.scalar_effects:
        return step_scalar(state, inputs, sp)
    return step_vector(state, inputs, sp)


def refresh_ttl(state: SensorState, job) -> SensorState:
    """Run the time-to-limit refresh a step left (``job`` from :func:`step_deferred`; None: nothing due)."""
    if job is None:
        return state
    if isinstance(job, tuple):
        return state._replace(ttl_s=_time_to_limit(*job))
    ttl = np.array(state.ttl_s, dtype=float, copy=True)
    for v, args in job:
        ttl[v] = _time_to_limit(*args)
    return state._replace(ttl_s=ttl)


def _ttl_phase(k, every):
    """Steps since the time to limit was last refreshed (it is refreshed after the steps k = 0, every, 2 every...)."""
    k = np.asarray(k)
    return np.where(k == 0, 0, (k - 1) % every + 1)


def step_vector(state: SensorState, inputs: SensorInputs, sp: SensorParams):
    """:func:`step` vectorised over any batch shape (numpy)."""
    rp, opt, lim, eff = sp.reduced, sp.options, sp.limits, sp.effects
    h = R.helpers(rp)
    dt = rp.dt_s
    B = state.t_last_s.shape
    raw = _raw_inputs(inputs, B)                                                 # B + (8,)
    finite = np.isfinite(raw)
    counts = np.zeros(B + (NR,), dtype=np.int64)

    # ---- time (optional frame time in the inputs)
    t_now = np.broadcast_to(np.asarray(inputs.t_s, dtype=float), B)
    if np.isfinite(t_now).any() or state.t_last_s.size == 0:
        gap = t_now - state.t_last_s
        known = np.isfinite(gap)
        backward = known & (gap < 0.5 * dt)
        jump = known & (gap > 1.5 * dt)
        counts[..., RJ["time_backward"]] += backward
        counts[..., RJ["time_jump"]] += jump
        if backward.any():
            return _skip(state, counts, backward, sp)
        if jump.any():
            state = _jump(state, np.where(jump, gap - dt, 0.0), sp)

    # ---- inputs: check, repair, hold (docs/sensor.md "Bad input")
    hold = state.hold
    ok = finite.copy()
    spd, tq, gr, oil = raw[..., I_SPEED], raw[..., I_TORQUE], raw[..., I_GEAR], raw[..., I_OIL]
    counts[..., RJ["speed_missing"]] += ~finite[..., I_SPEED]
    counts[..., RJ["torque_missing"]] += ~finite[..., I_TORQUE]
    counts[..., RJ["gear_missing"]] += ~finite[..., I_GEAR]
    spd_c = np.minimum(np.maximum(spd, 0.0), rp.max_speed_rpm)
    tq_c = np.minimum(np.maximum(tq, rp.min_torque_nm), rp.max_torque_nm)
    counts[..., RJ["speed_clamped"]] += finite[..., I_SPEED] & (spd_c != spd)
    counts[..., RJ["torque_clamped"]] += finite[..., I_TORQUE] & (tq_c != tq)
    gear_ok = finite[..., I_GEAR] & (gr == np.round(gr)) & (gr >= GEAR_MIN) & (gr <= GEAR_MAX)
    counts[..., RJ["gear_unknown"]] += finite[..., I_GEAR] & ~gear_ok
    ok[..., I_GEAR] = gear_ok
    # oil: plausible range, no implausible step from a recent good value, not frozen while the twin's sump moves
    oil_ok = finite[..., I_OIL] & (oil >= opt.oil_range_c[0]) & (oil <= opt.oil_range_c[1])
    jumpy = oil_ok & (state.age_s[..., I_OIL] <= 1.0) & (np.abs(oil - hold[..., I_OIL]) > opt.oil_step_c)
    same = np.where(finite & (raw == state.raw_prev), state.same_s + dt, 0.0)
    twin_oil = state.T_c[..., TWIN, rp.i_oil]
    oil_ref = np.where(same[..., I_OIL] > 0, state.oil_ref_c, twin_oil)
    oil_frozen = oil_ok & (same[..., I_OIL] >= opt.oil_frozen_s) & (np.abs(twin_oil - oil_ref) >= opt.oil_frozen_drift_c)
    counts[..., RJ["oil_missing"]] += ~finite[..., I_OIL]
    counts[..., RJ["oil_implausible"]] += (finite[..., I_OIL] & ~oil_ok) | jumpy
    counts[..., RJ["oil_frozen"]] += oil_frozen
    oil_ok = oil_ok & ~jumpy & ~oil_frozen
    ok[..., I_OIL] = oil_ok
    drive_frozen = (same[..., I_SPEED] >= opt.drive_frozen_s) & (same[..., I_TORQUE] >= opt.drive_frozen_s) & (spd_c > 0)
    counts[..., RJ["drive_frozen"]] += drive_frozen
    aux = raw[..., I_AMB:I_VKMH]
    ok[..., I_AMB:I_VKMH] = finite[..., I_AMB:I_VKMH] & (aux >= opt.aux_range_c[0]) & (aux <= opt.aux_range_c[1])
    vk = raw[..., I_VKMH]
    ok[..., I_VKMH] = finite[..., I_VKMH] & (vk >= 0) & (vk <= opt.max_vehicle_speed_kmh)
    counts[..., RJ["aux_missing"]] += np.add.reduce(~ok[..., I_AMB:], axis=-1)
    fixed = raw.copy()
    fixed[..., I_SPEED] = spd_c
    fixed[..., I_TORQUE] = tq_c
    fixed[..., I_RET] = np.abs(raw[..., I_RET])
    used = np.where(ok, fixed, hold)
    # auxiliary inputs are not held: a missing one takes its default
    used[..., I_AMB:] = np.where(ok[..., I_AMB:], fixed[..., I_AMB:], sp.aux_default)
    age = np.where(ok, 0.0, state.age_s + dt)
    drive_ok = ok[..., I_SPEED] & ok[..., I_TORQUE] & ok[..., I_GEAR]
    drive_age = np.maximum(np.maximum(age[..., I_SPEED], age[..., I_TORQUE]), age[..., I_GEAR])
    measured = oil_ok if opt.oil_mode == "measured" else np.zeros(B, dtype=bool)

    # ---- operating point
    w_in = used[..., I_SPEED] * R.RPM
    Tq = np.abs(used[..., I_TORQUE])
    row = used[..., I_GEAR].astype(np.int64) - GEAR_MIN
    T = np.array(state.T_c, dtype=float)
    T_main_oil = np.where(measured, oil, T[..., MAIN, rp.i_oil])
    T[..., MAIN, rp.i_oil] = T_main_oil
    x, prop, phi = R.oil_row(rp, T_main_oil, h)
    T_bc = np.empty(B + (len(BOUNDARIES),))
    T_bc[...] = sp.bc
    T_bc[..., rp.i_ambient] = used[..., I_AMB]
    T_bc[..., rp.i_coolant] = used[..., I_COOL]

    # ---- heat (loss maps) through the heat lag (exact step average for a held input)
    ret_w = eff.retarder_frac * used[..., I_RET] * np.abs(rp.speed_coef[row, 3]) * w_in
    src = R.heat_sources(rp, row, w_in, Tq, prop, x, eff.src_scale, eff.churn_scale, eff.needle_scale, ret_w, h)
    lag = state.lag_w + (src - state.lag_w) * sp.a_lag
    delivered = src - sp.lag_ratio * (lag - state.lag_w)
    q = delivered @ rp.src_matrix                                               # B + (n,)

    # ---- conductances (at the centre of the operating-point bin), cooler, inlet drop
    G, Gs = _conductances_q(sp, row, w_in, T_main_oil, h)
    T_oils = T[..., :, rp.i_oil]                                                 # B + (2,)
    w_ls = np.abs(rp.speed_coef[row, 1]) * w_in
    rho_cp = prop[..., R.P_RHO] * prop[..., R.P_CP]
    Q_cool, mcp, _ = R.cooler_heat(rp, T_oils, w_ls[..., None], w_in[..., None], used[..., I_COOL, None],
                                   used[..., I_AMB, None], used[..., I_VKMH, None], rho_cp[..., None],
                                   sp.cooler_scale, sp.thermostat_offset)
    dT_in = np.minimum(np.maximum(np.where(mcp > 0, Q_cool / np.where(mcp > 0, mcp, 1.0), 0.0), -INLET_DROP_MAX_K),
                       INLET_DROP_MAX_K)
    q2 = q[..., None, :] + (Gs[..., None, :] * dT_in[..., :, None]) @ h.stream_scatter            # B + (2, n)
    q2[..., rp.i_oil] -= Q_cool

    # ---- one explicit (forward Euler) step of both copies
    # copies first: (2, ..., n), so that the per-vehicle conductances broadcast over one leading axis
    T_new = np.moveaxis(R.explicit_step(np.moveaxis(T, -2, 0), np.moveaxis(q2, -2, 0), G[..., h.int_idx],
                                        G[..., h.ext_idx], T_bc, h.ia, h.ib, h.ea, h.eb, sp.dt_inv_C, h.B_int,
                                        h.B_ext), 0, -2)
    T_new[..., MAIN, rp.i_oil] = np.where(measured, oil, T_new[..., MAIN, rp.i_oil])

    # ---- outputs, time to limit (refreshed every ttl_period_s, counted down in between), warnings
    T_pub = T_new[..., MAIN, rp.published_index]
    available = drive_age <= opt.hold_s
    ttl = state.ttl_s
    phase = _ttl_phase(state.k, sp.ttl_every)
    ttl_now = np.maximum(ttl - (phase * dt)[..., None], 0.0)
    level, pend = update_levels(state.level, state.pending_s, T_pub, available, lim, dt, ttl_now)
    # the time-to-limit refresh of this step's state, run after the outputs (see refresh_ttl)
    due = state.k % sp.ttl_every == 0
    job = None
    if due.any():
        job = [(v, (sp, T_new[v][MAIN].copy(), src[v], G[v], Gs[v], float(dT_in[v][MAIN]), float(Q_cool[v][MAIN]),
                    bool(measured[v]), int(row[v]), float(w_in[v]), float(T_main_oil[v]), T_bc[v], used[v],
                    float(rho_cp[v]))) for v in (np.ndindex(B) if B else [()]) if due[v]]
    ttl_out = np.where(level == LEVEL_NA, np.nan, np.where(T_pub >= lim.warning_c, 0.0, ttl_now))
    mode = np.where(~drive_ok, MODE_HOLDING, np.where(measured, MODE_NORMAL, MODE_OIL_MODEL)).astype(np.int8)
    twin_new = T_new[..., TWIN, rp.i_oil]
    innov = np.where(oil_ok, oil - twin_new, np.nan)
    frozen_bits = (drive_frozen * ((1 << I_SPEED) | (1 << I_TORQUE))) | (oil_frozen * (1 << I_OIL))
    rejects = state.rejects + counts
    status = SensorStatus(mode, ok[..., I_SPEED], ok[..., I_TORQUE], ok[..., I_GEAR], oil_ok, ok @ _BITS,
                          twin_new, innov, (~measured).astype(np.int8), frozen_bits, rejects)
    new_state = SensorState(T_new, lag, np.where(ok, used, hold), age, same, raw, oil_ref, level, pend, ttl,
                            np.where(np.isfinite(t_now), t_now, state.t_last_s), state.k + 1, rejects)
    return new_state, SensorOutputs(T_pub, level, ttl_out, status), job


_BITS = (1 << np.arange(8)).astype(np.int64)


# ---------------------------------------------------------------------------------------------------------------
# the single-vehicle step in scalar arithmetic


class _ScalarTables:
    """Python-list views of a ReducedParams for scalar arithmetic (derived once per parameter set)."""

    def __init__(self, sp: SensorParams):
        rp = sp.reduced
        eff = sp.effects
        src_scale = np.broadcast_to(np.asarray(eff.src_scale, dtype=float), (R.N_SRC,))
        self.src_scale = src_scale.tolist()
        n_m = len(R.MESHES)
        self.mesh_phi = rp.mesh_phi.tolist()
        self.nx = rp.mesh_phi.shape[1]
        self.rows = []
        for row in range(rp.speed_coef.shape[0]):
            meshes = [(m, float(rp.mesh_torque[row, m]), float(rp.mesh_omega2[row, m]), float(rp.mesh_x0[m]),
                       float(rp.mesh_roll_k[m]), float(rp.mesh_heat_sf[m]) * self.src_scale[m])
                      for m in range(n_m) if rp.mesh_torque[row, m] > 0 and rp.mesh_omega2[row, m] > 0]
            bears = [(j, float(rp.bear_speed[row, j]), float(rp.bear_c[j]), float(rp.bear_load[row, j]))
                     for j in range(rp.bear_speed.shape[1])]
            needles = [(float(rp.needle_rel[row, j]), float(rp.needle_c[j])) for j in range(rp.needle_rel.shape[1])
                       if rp.needle_rel[row, j] > 0]
            self.rows.append((meshes, bears, needles, float(rp.sync_coef[row]), float(rp.pump_coef[row]),
                              abs(float(rp.speed_coef[row, 1])), abs(float(rp.speed_coef[row, 3]))))
        self.prop = rp.prop.tolist()
        self.nT = rp.prop.shape[0]
        self.T0 = float(R.T_GRID_C[0])
        self.dT = float(R.T_GRID_C[1] - R.T_GRID_C[0])
        self.Tmax = float(R.T_GRID_C[-1])
        self.churn = rp.churn_table.tolist()
        self.churn_w_max = rp.churn_w_max
        self.churn_sf = rp.churn_heat_sf * float(eff.churn_scale)
        self.needle_scale = float(eff.needle_scale)
        self.bear_scale = self.src_scale[R.I_SRC_BEARING:R.I_SRC_OIL]
        self.oil_scale = self.src_scale[R.I_SRC_OIL]
        self.ret_scale = self.src_scale[R.I_SRC_RET]
        self.retarder_frac = float(eff.retarder_frac)
        self.cooler_scale = float(eff.cooler_scale)
        self.thermostat_offset = float(eff.thermostat_offset_c)
        self.bc = np.asarray(sp.bc, dtype=float)
        self.aux_default = sp.aux_default.tolist()
        self.warn_minus_hyst = np.asarray(sp.limits.warning_c - sp.limits.hysteresis_k)
        self.zero_levels = np.zeros(N_PUB, dtype=np.int8)
        self.zero_pending = np.zeros(N_PUB)


_SCALAR_TABLES: dict = {}


def _scalar_tables(sp: SensorParams) -> _ScalarTables:
    item = _SCALAR_TABLES.get(id(sp))
    if item is None or item[0] is not sp:
        item = (sp, _ScalarTables(sp))
        _SCALAR_TABLES[id(sp)] = item
        if len(_SCALAR_TABLES) > 32:
            _SCALAR_TABLES.pop(next(iter(_SCALAR_TABLES)))
    return item[1]


_LN10 = math.log(10.0)
_RPM_TO_NU_N = 30.0 / math.pi
_NU_N_MIN = R.L.PALMGREN_NU_N_MIN


def _oil_props_scalar(tb: _ScalarTables, T_oil_c: float) -> tuple[float, list]:
    """(position on the oil-temperature grid, oil property row interpolated there) for one oil temperature."""
    xT = (min(max(T_oil_c, tb.T0), tb.Tmax) - tb.T0) / tb.dT
    i = min(int(xT), tb.nT - 2)
    f = xT - i
    return xT, [a * (1.0 - f) + b * f for a, b in zip(tb.prop[i], tb.prop[i + 1])]


def _heat_scalar(tb: _ScalarTables, row: int, w: float, Tq: float, pr: list, xT: float, ret_w: float) -> list:
    """heat_sources() for one vehicle, written for scalars (only the loaded meshes are evaluated)."""
    meshes, bears, needles, sync_c, pump_c, ls_c, _ = tb.rows[row]
    src = [0.0] * R.N_SRC
    log10mu = pr[R.P_LOG10_MU]
    ln_roll = pr[R.P_LN_ROLL]
    nx1 = tb.nx - 1.000001
    for m, tc, wc, x0, kroll, sf in meshes:
        T1 = tc * Tq
        w2 = wc * w
        if T1 <= 0.0 or w2 <= 0.0:
            continue
        lT = math.log10(T1)
        lw = math.log10(w2)
        x = (lT - log10mu - 3.0 * lw - x0) / R.X_STEP
        x = 0.0 if x < 0.0 else (nx1 if x > nx1 else x)
        ix = int(x)
        fx = x - ix
        tab = tb.mesh_phi[m]
        phi = tab[ix] * (1.0 - fx) + tab[ix + 1] * fx
        src[m] = T1 * w2 * (phi + kroll * math.exp(ln_roll + _LN10 * (0.7 * lw - 1.13 * lT))) * sf
    nu = math.exp(pr[R.P_LN_NU_CST])
    for (j, bs, bc, bl), scale in zip(bears, tb.bear_scale):
        wb = bs * w
        nn = nu * wb * _RPM_TO_NU_N
        src[R.I_SRC_BEARING + j] = (bc * (nn if nn > _NU_N_MIN else _NU_N_MIN) ** (2.0 / 3.0) + bl * Tq) * wb * scale
    P_needle = 0.0
    for rel_c, c in needles:
        rel = rel_c * w
        nn = nu * rel * _RPM_TO_NU_N
        P_needle += c * (nn if nn > _NU_N_MIN else _NU_N_MIN) ** (2.0 / 3.0) * rel
    w2in = w * w
    P_sync = math.exp(pr[R.P_LN_MU]) * w2in * sync_c
    P_pump = pump_c * w2in
    w_ls = ls_c * w
    r = w_ls / tb.churn_w_max
    uu = math.sqrt(r if r < 1.0 else 1.0) * (R.N_U_CHURN - 1)
    iu = min(int(uu), R.N_U_CHURN - 2)
    fu = uu - iu
    jT = min(int(xT), tb.nT - 2)
    fT = xT - jT
    c0, c1 = tb.churn[iu], tb.churn[iu + 1]
    lo = c0[jT] * (1.0 - fT) + c0[jT + 1] * fT
    hi = c1[jT] * (1.0 - fT) + c1[jT + 1] * fT
    P_churn = lo + (hi - lo) * fu
    src[R.I_SRC_OIL] = (P_churn * tb.churn_sf + P_needle * tb.needle_scale + P_sync + P_pump) * tb.oil_scale
    src[R.I_SRC_RET] = ret_w * tb.ret_scale
    return src


def _cooler_scalar(rp: R.ReducedParams, tb, T_oil, w_ls, w_eng, T_cool, T_amb, v_kmh, rho_cp):
    """cooler_heat() for one sump temperature, in scalars: (Q [W], mdot cp [W/K])."""
    mcp = rho_cp * rp.flow_m3_per_rad * w_ls
    if rp.cooler_code == 0 or mcp <= 0.0:
        return 0.0, mcp
    c = rp.cooler
    inner = (w_ls / c["ref_ls_speed"]) ** c["exp_inner"]
    if rp.cooler_code == 1:
        outer = ((w_eng if w_eng > 0 else 0.0) / c["ref_engine_speed"]) ** c["exp_outer"]
        hA = c["liquid_hA_ref"] * inner * outer * tb.cooler_scale
        Q = hA * (T_oil - T_cool)
        return min(max(Q, -c["liquid_Qmax_heat"]), c["liquid_Qmax_cool"]), mcp
    Q = float(R.cooler_heat(rp, T_oil, w_ls, w_eng, T_cool, T_amb, v_kmh, rho_cp, tb.cooler_scale,
                            tb.thermostat_offset)[0])
    return Q, mcp


def step_scalar(state: SensorState, inputs: SensorInputs, sp: SensorParams):
    """:func:`step` for one vehicle: the same arithmetic as :func:`step_vector` in Python scalars where the data are
    scalar, numpy only for the network vectors."""
    rp, opt, lim = sp.reduced, sp.options, sp.limits
    tb = _scalar_tables(sp)
    h = R.helpers(rp)
    dt = rp.dt_s
    raw = [float(v) for v in inputs[:8]]
    t_now = float(inputs.t_s)
    counts = [0] * NR
    t_last = float(state.t_last_s)
    if t_now == t_now and t_last == t_last:
        gap = t_now - t_last
        if gap < 0.5 * dt:
            counts[RJ["time_backward"]] += 1
            return _skip(state, np.array(counts, dtype=np.int64), np.bool_(True), sp)
        if gap > 1.5 * dt:
            counts[RJ["time_jump"]] += 1
            state = _jump(state, np.float64(gap - dt), sp)
    hold = state.hold.tolist()
    age_prev = state.age_s.tolist()
    same_prev = state.same_s.tolist()
    raw_prev = state.raw_prev.tolist()
    fin = [v - v == 0.0 for v in raw]                         # finite (NaN and inf give False)
    ok = list(fin)
    spd, tq, gr, oil = raw[I_SPEED], raw[I_TORQUE], raw[I_GEAR], raw[I_OIL]
    if not fin[I_SPEED]:
        counts[RJ["speed_missing"]] += 1
    if not fin[I_TORQUE]:
        counts[RJ["torque_missing"]] += 1
    if not fin[I_GEAR]:
        counts[RJ["gear_missing"]] += 1
    spd_c = min(max(spd, 0.0), rp.max_speed_rpm) if fin[I_SPEED] else spd
    tq_c = min(max(tq, rp.min_torque_nm), rp.max_torque_nm) if fin[I_TORQUE] else tq
    if fin[I_SPEED] and spd_c != spd:
        counts[RJ["speed_clamped"]] += 1
    if fin[I_TORQUE] and tq_c != tq:
        counts[RJ["torque_clamped"]] += 1
    gear_ok = fin[I_GEAR] and gr == round(gr) and GEAR_MIN <= gr <= GEAR_MAX
    if fin[I_GEAR] and not gear_ok:
        counts[RJ["gear_unknown"]] += 1
    ok[I_GEAR] = gear_ok
    oil_ok = fin[I_OIL] and opt.oil_range_c[0] <= oil <= opt.oil_range_c[1]
    jumpy = oil_ok and age_prev[I_OIL] <= 1.0 and abs(oil - hold[I_OIL]) > opt.oil_step_c
    same = [same_prev[i] + dt if (fin[i] and raw[i] == raw_prev[i]) else 0.0 for i in range(8)]
    T = np.array(state.T_c, dtype=float)
    twin_oil = float(T[TWIN, rp.i_oil])
    oil_ref = float(state.oil_ref_c) if same[I_OIL] > 0 else twin_oil
    oil_frozen = oil_ok and same[I_OIL] >= opt.oil_frozen_s and abs(twin_oil - oil_ref) >= opt.oil_frozen_drift_c
    if not fin[I_OIL]:
        counts[RJ["oil_missing"]] += 1
    if (fin[I_OIL] and not oil_ok) or jumpy:
        counts[RJ["oil_implausible"]] += 1
    if oil_frozen:
        counts[RJ["oil_frozen"]] += 1
    oil_ok = oil_ok and not jumpy and not oil_frozen
    ok[I_OIL] = oil_ok
    drive_frozen = same[I_SPEED] >= opt.drive_frozen_s and same[I_TORQUE] >= opt.drive_frozen_s and spd_c > 0
    if drive_frozen:
        counts[RJ["drive_frozen"]] += 1
    lo_a, hi_a = opt.aux_range_c
    for i in (I_AMB, I_COOL):
        ok[i] = fin[i] and lo_a <= raw[i] <= hi_a
    ok[I_VKMH] = fin[I_VKMH] and 0.0 <= raw[I_VKMH] <= opt.max_vehicle_speed_kmh
    counts[RJ["aux_missing"]] += sum(1 for i in range(I_AMB, 8) if not ok[i])
    fixed = list(raw)
    fixed[I_SPEED] = spd_c
    fixed[I_TORQUE] = tq_c
    fixed[I_RET] = abs(raw[I_RET])
    used = [fixed[i] if ok[i] else hold[i] for i in range(8)]
    for i in range(I_AMB, 8):
        used[i] = fixed[i] if ok[i] else tb.aux_default[i - I_AMB]
    age = [0.0 if ok[i] else age_prev[i] + dt for i in range(8)]
    drive_ok = ok[I_SPEED] and ok[I_TORQUE] and ok[I_GEAR]
    drive_age = max(age[I_SPEED], age[I_TORQUE], age[I_GEAR])
    measured = oil_ok and opt.oil_mode == "measured"

    # ---- operating point
    w_in = used[I_SPEED] * R.RPM
    Tq = abs(used[I_TORQUE])
    row = int(used[I_GEAR]) - GEAR_MIN
    T_main_oil = oil if measured else float(T[MAIN, rp.i_oil])
    T[MAIN, rp.i_oil] = T_main_oil
    xT, pr = _oil_props_scalar(tb, T_main_oil)
    T_bc = tb.bc.copy()
    T_bc[rp.i_ambient] = used[I_AMB]
    T_bc[rp.i_coolant] = used[I_COOL]

    # ---- heat through the lag
    _, _, _, _, _, ls_c, os_c = tb.rows[row]
    ret_w = tb.retarder_frac * used[I_RET] * os_c * w_in
    src = np.array(_heat_scalar(tb, row, w_in, Tq, pr, xT, ret_w))
    lag0 = state.lag_w
    lag = lag0 + (src - lag0) * sp.a_lag
    q = (src - sp.lag_ratio * (lag - lag0)) @ rp.src_matrix

    # ---- conductances (cached per quantised operating point), cooler, inlet drop
    it = _key_item(sp, row, w_in, T_main_oil, h)
    w_ls = ls_c * w_in
    rho_cp = pr[R.P_RHO] * pr[R.P_CP]
    Qc = [0.0, 0.0]
    dTin = [0.0, 0.0]
    for c in (MAIN, TWIN):
        Q, mcp = _cooler_scalar(rp, tb, float(T[c, rp.i_oil]), w_ls, w_in, used[I_COOL], used[I_AMB],
                                used[I_VKMH], rho_cp)
        d = Q / mcp if mcp > 0 else 0.0
        Qc[c], dTin[c] = Q, min(max(d, -INLET_DROP_MAX_K), INLET_DROP_MAX_K)
    q2 = q + np.array(dTin)[:, None] * it.sv                  # = np.outer(dTin, sv), without its overhead
    q2[:, rp.i_oil] -= Qc

    # ---- one explicit step of both copies: T_new = T M + dt/C (c + sources), M = I - dt C^-1 K (per bin)
    T_new = T @ it.M + (it.c_dt + sp.dt_inv_C * q2)
    if measured:
        T_new[MAIN, rp.i_oil] = oil

    # ---- outputs, time to limit (refreshed every ttl_period_s, counted down in between), warnings
    T_pub = T_new[MAIN, rp.published_index]
    available = drive_age <= opt.hold_s
    ttl = state.ttl_s
    k = int(state.k)
    ttl_now = ttl if k == 0 else np.maximum(ttl - ((k - 1) % sp.ttl_every + 1) * dt, 0.0)
    lv0 = state.level
    if (available and (T_pub - tb.warn_minus_hyst).max() < 0.0 and not lv0.any() and not state.pending_s.any()
            and (lim.lead_s <= 0 or ttl_now.min() > 2.0 * lim.lead_s)):
        level, pend = tb.zero_levels, tb.zero_pending           # nothing near a limit: the state machine rests
    else:
        level, pend = update_levels(lv0, state.pending_s, T_pub, available, lim, dt, ttl_now)
    if level.any() or (T_pub >= lim.warning_c).any():
        ttl_out = np.where(level == LEVEL_NA, np.nan, np.where(T_pub >= lim.warning_c, 0.0, ttl_now))
    else:
        ttl_out = ttl_now
    mode = MODE_HOLDING if not drive_ok else (MODE_NORMAL if measured else MODE_OIL_MODEL)
    twin_new = float(T_new[TWIN, rp.i_oil])
    flags = (ok[0] | ok[1] << 1 | ok[2] << 2 | ok[3] << 3 | ok[4] << 4 | ok[5] << 5 | ok[6] << 6 | ok[7] << 7)
    frozen_bits = (((1 << I_SPEED) | (1 << I_TORQUE)) if drive_frozen else 0) | ((1 << I_OIL) if oil_frozen else 0)
    rejects = state.rejects + np.array(counts, dtype=np.int64) if any(counts) else state.rejects
    status = SensorStatus(np.int8(mode), ok[I_SPEED], ok[I_TORQUE], ok[I_GEAR], oil_ok, flags, twin_new,
                          oil - twin_new if oil_ok else math.nan, np.int8(0 if measured else 1), frozen_bits,
                          rejects)
    new_hold = np.array([used[i] if ok[i] else hold[i] for i in range(8)])
    new_state = SensorState(T_new, lag, new_hold, np.array(age), np.array(same), np.array(raw), np.float64(oil_ref),
                            level, pend, ttl, np.float64(t_now if t_now == t_now else t_last), state.k + 1, rejects)
    job = None
    if k % sp.ttl_every == 0:
        # the time-to-limit refresh of this step's state, run after the outputs (see refresh_ttl)
        job = (sp, T_new[MAIN].copy(), src, it.G, it.Gs, dTin[MAIN], Qc[MAIN], measured, row, w_in, T_main_oil, T_bc,
               np.array(used), rho_cp)
    return new_state, SensorOutputs(T_pub, level, ttl_out, status), job


_SIGMA = R.ht.SIGMA_W_PER_M2K4


class _KeyItem(NamedTuple):
    G: np.ndarray        # (nl,) conductances at the bin centre
    Gs: np.ndarray       # (nst,) stream conductances
    sv: np.ndarray       # (n,) Gs @ stream_scatter: the inlet-drop transfer per kelvin
    M: np.ndarray        # (n, n) Euler matrix I - dt C^-1 K
    c_dt: np.ndarray     # (n,) dt/C x heat from the boundary links
    K: np.ndarray        # (n, n) the network's conductance matrix
    key: tuple           # (gear row, speed bin, oil bin centre)


def _key_item(sp: SensorParams, row: int, w_in: float, T_oil: float, h) -> _KeyItem:
    """Everything that depends only on the quantised operating point, cached (a bounded memo of a pure function)."""
    if w_in >= SPEED_BIN_MIN_RAD_S:
        b = round(math.log(w_in) / _LN_BIN)
    else:
        b = None
    T_q = round(T_oil / OIL_BIN_C) * OIL_BIN_C
    key = (row, b, T_q)
    cache = sp.kcache
    item = cache.get(key)
    if item is not None:
        return item
    rp = sp.reduced
    w_q = math.exp(b * _LN_BIN) if b is not None else 0.0
    x, prop, phi = R.oil_row(rp, T_q, h)
    G, Gs = R.conductances(rp, row, w_q, x, prop, phi, None, None, sp.effects, h, radiation=False)
    if rp.rad_link.size:
        G[rp.rad_link] = _radiation_at(sp, T_q, h)
    n = rp.n
    K, Ge = _conductance_matrix(G, h, n)
    M = np.eye(n) - K * sp.dt_inv_C[None, :]
    c = np.bincount(h.ea, Ge * np.asarray(sp.bc, dtype=float)[h.eb], minlength=n) * sp.dt_inv_C
    item = _KeyItem(G, Gs, Gs @ h.stream_scatter, M, c, K, key)
    cache[key] = item
    if len(cache) > 256:
        cache.pop(next(iter(cache)))
    return item


def _conductance_matrix(G, h, n: int):
    """(K, G_ext): the network's conductance matrix (weighted Laplacian plus the boundary links on the diagonal) of
    one vehicle's link conductances G, and the boundary links' conductances."""
    Gi = G[h.int_idx]
    K = np.zeros((n, n))
    np.add.at(K, (h.ia, h.ia), Gi)
    np.add.at(K, (h.ib, h.ib), Gi)
    np.add.at(K, (h.ia, h.ib), -Gi)
    np.add.at(K, (h.ib, h.ia), -Gi)
    Ge = G[h.ext_idx]
    np.add.at(K, (h.ea, h.ea), Ge)
    return K, Ge


def _skip(state: SensorState, counts, skip_mask, sp: SensorParams):
    """A step whose time went backwards: nothing is integrated; outputs repeat the current state."""
    rp = sp.reduced
    rejects = state.rejects + counts
    st = state._replace(rejects=rejects)
    B = state.t_last_s.shape
    T_pub = state.T_c[..., MAIN, rp.published_index]
    z = np.zeros(B, dtype=bool)
    status = SensorStatus(np.full(B, MODE_HOLDING, dtype=np.int8), z, z, z, z, np.zeros(B, dtype=np.int64),
                          state.T_c[..., TWIN, rp.i_oil], np.full(B, np.nan), np.ones(B, dtype=np.int8),
                          np.zeros(B, dtype=np.int64), rejects)
    if np.all(skip_mask):
        return st, SensorOutputs(T_pub, state.level, state.ttl_s, status), None
    raise InputError("time went backwards for some vehicles of a batch only; step the batch on one time grid")


# ---------------------------------------------------------------------------------------------------------------
# held inputs: linear system, time to limit, time jumps, cool-down


def _linear_system(sp: SensorParams, G, q_nodes, xfer_nodes, T_bc, T_oil_c, Q_cool, measured, cooler_slope):
    """(K, b, free) of C dT/dt = -K T + b for the main network with everything held."""
    rp = sp.reduced
    h = R.helpers(rp)
    n = rp.n
    K, Ge = _conductance_matrix(G, h, n)
    b = q_nodes + xfer_nodes + np.bincount(h.ea, Ge * T_bc[h.eb], minlength=n)
    if measured:
        free = np.flatnonzero(np.arange(n) != rp.i_oil)
        b = b - K[:, rp.i_oil] * T_oil_c
    else:
        free = np.arange(n)
        # cooler linearised at the current sump: Q = Q0 + g (T - T0)
        K[rp.i_oil, rp.i_oil] += cooler_slope
        b[rp.i_oil] += cooler_slope * T_oil_c - Q_cool
    return K, b, free


def _cooler_slope(sp, T_oil, w_in, row, used, rho_cp):
    """dQ_cooler/dT_oil [W/K] at this operating point (liquid: hA unless saturated; air: finite difference)."""
    rp = sp.reduced
    w_ls = abs(rp.speed_coef[row, 1]) * w_in
    if rp.cooler_code == 0 or w_ls <= 0.0:
        return 0.0
    c = rp.cooler
    if rp.cooler_code == 1:
        hA = (c["liquid_hA_ref"] * (w_ls / c["ref_ls_speed"]) ** c["exp_inner"]
              * (max(w_in, 0.0) / c["ref_engine_speed"]) ** c["exp_outer"] * _scalar(sp.effects.cooler_scale))
        Q = hA * (T_oil - float(used[I_COOL]))
        return hA if -c["liquid_Qmax_heat"] < Q < c["liquid_Qmax_cool"] else 0.0
    args = (w_ls, w_in, used[I_COOL], used[I_AMB], used[I_VKMH], rho_cp, _scalar(sp.effects.cooler_scale),
            _scalar(sp.effects.thermostat_offset_c))
    q1 = R.cooler_heat(rp, T_oil + 0.05, *args)[0]
    q0 = R.cooler_heat(rp, T_oil - 0.05, *args)[0]
    return max(float((q1 - q0) / 0.1), 0.0)


def _scalar(v):
    a = np.asarray(v, dtype=float)
    return float(a) if a.ndim == 0 else float(a.reshape(-1)[0])


#: bin of the cooler slope dQ/dT_oil in the cached held-input modes (model-oil mode) [W/K]
SLOPE_BIN_W_PER_K = 10.0
#: operating-point bins of the cached held-input modes: 1 % in speed (4 % made the coupled inlet ~4 % slow on the
#: uphill cycle: the coupling column scales with speed), 2 K in oil temperature
TTL_SPEED_BIN_REL = 0.01
TTL_OIL_BIN_C = 2.0
_LN_TTL_BIN = math.log1p(TTL_SPEED_BIN_REL)


#: with the sump modelled: re-linearise the held-input system this many times at the sump temperature the last
#: solution predicts at the earliest crossing (the losses and oil-side conductances follow the sump; docs/sensor.md)
TTL_RELINEARISE_STEPS = 2
#: with the sump modelled: the oil-system inlet follows the sump through the linearised cooler in the held-input
#: system (a non-symmetric coupling, general eigen-decomposition; docs/sensor.md), unless the step clips it
TTL_INLET_COUPLING = True
#: ... until the operating point's sump temperature moves less than this [K]
TTL_RELINEARISE_TOL_K = 0.5


def _time_to_limit(sp, T_main, src, G, Gs, dT_in, Q_cool, measured, row, w_in, T_oil, T_bc, used, rho_cp):
    """Time [s] until each published component reaches its warning limit if the current inputs are held.

    With the sump modelled (``ttl_sump = "model"``) the sump warms or cools under the held load, and the losses and
    the oil-side conductances move with it: the system is re-linearised at the sump temperature the previous
    solution predicts at the earliest crossing (from the same state), up to TTL_RELINEARISE_STEPS times."""
    out, item, T_inf, slope = _ttl_solve(sp, T_main, src, G, Gs, dT_in, Q_cool, measured, row, w_in, T_oil, T_bc,
                                         used, rho_cp, T_oil)
    if sp.options.ttl_sump != "model" or not sp.scalar_effects:
        return out
    rp = sp.reduced
    h = R.helpers(rp)
    tb = _scalar_tables(sp)
    T_op = T_oil
    for _ in range(TTL_RELINEARISE_STEPS):
        cand = out[h.ttl_relin_pub]
        cand = cand[(cand > 0.0) & np.isfinite(cand)]
        if cand.size == 0:
            break
        T_next = float(HeldInputSolver.propagate(item, T_main[item[3]], T_inf, float(cand.min()))[rp.i_oil])
        if abs(T_next - T_op) < TTL_RELINEARISE_TOL_K:
            break
        T_op = T_next
        xT, pr = _oil_props_scalar(tb, T_op)
        ret_w = tb.retarder_frac * float(used[I_RET]) * tb.rows[row][6] * w_in
        src_op = np.array(_heat_scalar(tb, row, w_in, abs(float(used[I_TORQUE])), pr, xT, ret_w))
        it = _key_item(sp, row, w_in, T_op, h)
        out, item, T_inf, _ = _ttl_solve(sp, T_main, src_op, it.G, it.Gs, dT_in, Q_cool, measured, row, w_in, T_oil,
                                         T_bc, used, rho_cp, T_op)
    return out


def _inlet_follows_sump(sp, measured, sbin, dT_in, Q_cool, row, w_in, T_oil, T_op, rho_cp) -> bool:
    """Whether the held-input system couples the oil-system inlet to the sump (see :func:`_ttl_solve`): the sump is
    modelled, the cooler has a slope, and the inlet drop is inside the step's clip both now and, on the linearised
    cooler, at the operating point's sump T_op (a clipped inlet drop does not follow the sump)."""
    if not TTL_INLET_COUPLING or measured or sbin == 0 or not abs(dT_in) < INLET_DROP_MAX_K:
        return False
    mcp = rho_cp * _oil_flow_m3_s(sp, row, w_in)
    if not mcp > 0.0:
        return False
    return abs((Q_cool + sbin * SLOPE_BIN_W_PER_K * (T_op - T_oil)) / mcp) < INLET_DROP_MAX_K


def _rho_cp_scalar(sp, T_oil_c: float) -> float:
    """Volumetric heat capacity of the oil [J/(m3 K)] at one temperature (the step's property row)."""
    pr = _oil_props_scalar(_scalar_tables(sp), T_oil_c)[1]
    return pr[R.P_RHO] * pr[R.P_CP]


def _oil_flow_m3_s(sp, row: int, w_in: float) -> float:
    """Oil-system volume flow [m3/s] at this gear and input speed (the pump turns with the layshaft)."""
    rp = sp.reduced
    return rp.flow_m3_per_rad * abs(float(rp.speed_coef[row, 1])) * w_in


def _ttl_solve(sp, T_main, src, G, Gs, dT_in, Q_cool, measured, row, w_in, T_oil, T_bc, used, rho_cp, T_op):
    """One held-input solution: (time to limit, modes item, T_inf over the free nodes); T_oil is the sump the
    cooler is linearised at, T_op the oil temperature of the operating point (bins, losses, conductances).

    K (and its modes) at the quantised operating point of the conductance cache (plus radiation at the bin's oil
    temperature and, with the sump modelled, the cooler slope in 10 W/K bins): a pure function of the bin, cached.
    b (heat, boundaries, inlet drop, the measured sump) at the actual operating point."""
    rp = sp.reduced
    h = R.helpers(rp)
    if sp.options.ttl_sump == "model":
        measured = False           # the sump is a state that heats with the held load, from its measured value
    if sp.scalar_effects:
        # modes on their own grid (1 % in speed, 2 K in oil, the cooler slope at the bin centre in 10 W/K): few
        # eigen-decompositions while driving; T_inf and the modal coefficients still from the actual heat,
        # boundaries and inlet drop (b)
        wb = round(math.log(w_in) / _LN_TTL_BIN) if w_in >= SPEED_BIN_MIN_RAD_S else None
        Tb = round(T_op / TTL_OIL_BIN_C) * TTL_OIL_BIN_C
        w_c = math.exp(wb * _LN_TTL_BIN) if wb is not None else 0.0
        slope = 0.0 if measured else _cooler_slope(sp, Tb, w_c, row, used, rho_cp)
        sbin = 0 if measured else int(round(slope / SLOPE_BIN_W_PER_K))
        couple = _inlet_follows_sump(sp, measured, sbin, dT_in, Q_cool, row, w_in, T_oil, T_op, rho_cp)
        key = (row, wb, Tb, bool(measured), sbin, couple)
        item = sp.solver.cache.get(key)
        if item is None:
            it = _key_item(sp, row, w_c, Tb, h)
            # the inlet-coupling column at the bin centre (oil density and heat capacity at Tb)
            mcp_c = _oil_flow_m3_s(sp, row, w_c) * _rho_cp_scalar(sp, Tb)
            sv_c = it.sv
    else:                          # per-vehicle effects: the vehicle's own conductances, no cache
        it, key, item = None, None, None
        slope = 0.0 if measured else _cooler_slope(sp, T_oil, w_in, row, used, rho_cp)
        sbin = 0 if measured else int(round(slope / SLOPE_BIN_W_PER_K))
        couple = _inlet_follows_sump(sp, measured, sbin, dT_in, Q_cool, row, w_in, T_oil, T_op, rho_cp)
        mcp_c = _oil_flow_m3_s(sp, row, w_in) * rho_cp
        sv_c = Gs @ h.stream_scatter
    if item is not None:
        sp.solver.cache.move_to_end(key)
        sp.solver.hits += 1
    else:
        if it is not None:
            K = it.K.copy()
        else:
            K, _, _ = _linear_system(sp, G, np.zeros(rp.n), np.zeros(rp.n), T_bc, T_oil, 0.0, False, 0.0)
        coupling = None
        if measured:
            free = np.flatnonzero(np.arange(rp.n) != rp.i_oil)
        else:
            free = np.arange(rp.n)
            K[rp.i_oil, rp.i_oil] += sbin * SLOPE_BIN_W_PER_K
            if couple and mcp_c > 0.0:
                # the oil-system inlet follows the sump through the linearised cooler: inlet drop
                # (Q0 + slope (T_sump - T0)) / (mdot cp) moves sv (T_sump - T0) slope / (mdot cp) into the streams
                coupling = (sv_c * (sbin * SLOPE_BIN_W_PER_K / mcp_c), rp.i_oil)
        item = sp.solver.modes(key, K, free, coupling)
    n = rp.n
    if HeldInputSolver.coupled(item):
        # the inlet drop is dT_in at the current sump and follows it (the coupling column of the modes): its part
        # at the current sump goes into b
        b_in = (Gs * dT_in) @ h.stream_scatter - item[6] * T_oil
    else:
        # frozen inlet drop, at the operating point's sump T_op through the linearised cooler
        if T_op != T_oil and not measured:
            mcp = rho_cp * _oil_flow_m3_s(sp, row, w_in)
            d = (Q_cool + sbin * SLOPE_BIN_W_PER_K * (T_op - T_oil)) / mcp if mcp > 0.0 else 0.0
            dT_in = min(max(d, -INLET_DROP_MAX_K), INLET_DROP_MAX_K)
        b_in = (Gs * dT_in) @ h.stream_scatter
    b = src @ rp.src_matrix + b_in + np.bincount(h.ea, G[h.ext_idx] * T_bc[h.eb], minlength=n)
    if measured:
        # links to the (held) measured sump enter b
        Gi = G[h.int_idx]
        b = b + np.bincount(h.oil_other, Gi[h.oil_links] * T_oil, minlength=n)
    else:
        # cooler linearised at the current sump: Q = Q0 + g (T - T0)
        b[rp.i_oil] += sbin * SLOPE_BIN_W_PER_K * T_oil - Q_cool
    free = item[3]
    T_inf = HeldInputSolver.steady(item, b[free])
    pub_free, rows = (h.pub_free_meas, h.pub_rows_meas) if measured else (h.pub_free_all, h.pub_rows_all)
    out = np.full(N_PUB, np.inf)
    out[pub_free] = HeldInputSolver.time_to_limit(item, T_main[free], T_inf, rows, sp.limits.warning_c[pub_free])
    if measured:
        i_pub_oil = PUBLISHED.index("oil")
        out[i_pub_oil] = 0.0 if T_oil >= sp.limits.warning_c[i_pub_oil] else np.inf
    return out, item, T_inf, (0.0 if measured else sbin * SLOPE_BIN_W_PER_K)


def _jump(state: SensorState, gap_s, sp: SensorParams) -> SensorState:
    """Propagate over a forward time jump: held inputs for up to time_jump_hold_s, then engine off."""
    B = state.t_last_s.shape
    T = np.array(state.T_c, dtype=float, copy=True)
    for v in (np.ndindex(B) if B else [()]):
        g = float(np.asarray(gap_s)[v])
        if g <= 0:
            continue
        held = min(g, sp.options.time_jump_hold_s)
        for c in (MAIN, TWIN):
            T[v + (c,)] = _held_propagate(sp, state, v, c, held)
        if g > held:
            for c in (MAIN, TWIN):
                T[v + (c,)] = cool_down(sp, T[v + (c,)], g - held, _amb(state, v, sp))
    return state._replace(T_c=T)


def _amb(state, v, sp):
    a = float(state.hold[v + (I_AMB,)])
    return a if math.isfinite(a) else float(sp.reduced.bc_default_c[sp.reduced.i_ambient])


def _held_propagate(sp, state, v, copy, t_s):
    """Temperatures of one copy after t_s seconds with the last good inputs held (exact modal solution): the main
    copy keeps a measured sump at its last reading, the twin integrates its own."""
    rp = sp.reduced
    h = R.helpers(rp)
    hold = np.array(state.hold[v], dtype=float)
    T0 = np.array(state.T_c[v + (copy,)], dtype=float)

    def held(i, default):
        return float(hold[i]) if math.isfinite(hold[i]) else default
    spd, tq, gear = held(I_SPEED, 0.0), abs(held(I_TORQUE, 0.0)), int(held(I_GEAR, 0.0))
    amb = held(I_AMB, float(sp.aux_default[0]))
    cool = held(I_COOL, float(sp.aux_default[1]))
    vk = held(I_VKMH, float(sp.aux_default[2]))
    ret = abs(held(I_RET, 0.0))
    row = gear - GEAR_MIN
    w_in = spd * R.RPM
    measured = (copy == MAIN and sp.options.oil_mode == "measured" and float(np.asarray(state.age_s)[v + (I_OIL,)])
                == 0.0 and math.isfinite(hold[I_OIL]))
    T_oil = float(hold[I_OIL]) if measured else float(T0[rp.i_oil])
    T0[rp.i_oil] = T_oil
    x, prop, phi = R.oil_row(rp, T_oil, h)
    T_bc = np.array(np.asarray(sp.bc, dtype=float).reshape(-1, len(BOUNDARIES))[0])
    T_bc[rp.i_ambient], T_bc[rp.i_coolant] = amb, cool
    e = sp.effects
    ret_w = _scalar(e.retarder_frac) * ret * abs(rp.speed_coef[row, 3]) * w_in
    src = R.heat_sources(rp, row, w_in, tq, prop, x, _first(e.src_scale), _scalar(e.churn_scale),
                         _scalar(e.needle_scale), ret_w, h=h)
    G, Gs = R.conductances(rp, row, w_in, x, prop, phi, T0, T_bc, e if sp.scalar_effects else None, h)
    rho_cp = float(prop[R.P_RHO] * prop[R.P_CP])
    w_ls = abs(rp.speed_coef[row, 1]) * w_in
    used = np.array([spd, tq, gear, T_oil, amb, cool, vk, ret])
    Q, mcp, _ = R.cooler_heat(rp, T_oil, w_ls, w_in, cool, amb, vk, rho_cp, _scalar(e.cooler_scale),
                              _scalar(e.thermostat_offset_c))
    dT_in = float(np.clip(Q / mcp, -30, 30)) if mcp > 0 else 0.0
    q = src @ rp.src_matrix
    xfer = (Gs * dT_in) @ h.stream_scatter
    slope = 0.0 if measured else _cooler_slope(sp, T_oil, w_in, row, used, rho_cp)
    K, b, free = _linear_system(sp, G, q, xfer, T_bc, T_oil, float(Q), measured, slope)
    item = sp.solver.modes(None, K, free)
    T_inf = HeldInputSolver.steady(item, b[free])
    out = T0.copy()
    out[free] = HeldInputSolver.propagate(item, T0[free], T_inf, t_s)
    return out


def _first(a):
    a = np.asarray(a, dtype=float)
    return a if a.ndim <= 1 else a.reshape(-1, a.shape[-1])[0]


def cool_down(sp: SensorParams, T0, elapsed_s: float, ambient_c: float):
    """Node temperatures after ``elapsed_s`` with the engine off: no heat, no flow, no cooler, every boundary at
    ambient (the engine bay cools too). Exact for the linear engine-off network (every mode, the slowest last)."""
    rp = sp.reduced
    h = R.helpers(rp)
    T0 = np.asarray(T0, dtype=float)
    if elapsed_s <= 0:
        return T0.copy()
    key = ("off", round(ambient_c, 1))
    item = sp.solver.cache.get(key)
    if item is None:
        T_bc = np.full(len(BOUNDARIES), float(ambient_c))
        x, prop, phi = R.oil_row(rp, ambient_c, h)
        G, _ = R.conductances(rp, 0 - GEAR_MIN, 0.0, x, prop, phi, np.full(rp.n, ambient_c), T_bc, None, h)
        K, _, free = _linear_system(sp, G, np.zeros(rp.n), np.zeros(rp.n), T_bc, ambient_c, 0.0, False, 0.0)
        item = sp.solver.modes(key, K, free)
    free = item[3]
    T_inf = np.full(len(free), float(ambient_c))
    out = T0.copy()
    out[free] = HeldInputSolver.propagate(item, T0[free], T_inf, float(elapsed_s))
    return out


def slowest_time_constant_s(sp: SensorParams, ambient_c: float = 25.0) -> float:
    """Time constant of the slowest engine-off mode [s] (how fast a parked gearbox forgets)."""
    cool_down(sp, np.full(sp.reduced.n, ambient_c), 1.0, ambient_c)
    lam = sp.solver.cache[("off", round(ambient_c, 1))][0]
    return float(1.0 / lam.min())


# ---------------------------------------------------------------------------------------------------------------
# the sensor object


class VirtualSensor:
    """The onboard sensor: parameters built and checked once, then the pure :func:`step`.

    ``params``: a validated gearbox :class:`~firmware_model.parameters.Parameters`; ``limits``: a :class:`Limits`,
    the path of a limits TOML, or None (config [sensor] limits, else params/limits.toml); ``config``: a
    :class:`~firmware_model.config.Config` (its [sensor] section: oil_mode, limits, debounce_s, hysteresis_c);
    ``effects``: {effect id: value or per-vehicle array} for the effects in firmware_model.onboard.reduce.EFFECT_HOOKS
    (and oil_level_low, scalar); ``partition``: "fine" (default) or "compact"; ``options``: SensorOptions overrides.
    Raises StabilityError when the parameter set is unsafe for the 0.1 s explicit step.
    """
    Inputs = SensorInputs
    Status = SensorStatus
    Outputs = SensorOutputs
    #: names of the reject counters (SensorStatus.rejects), in order
    reject_reasons = REJECT_REASONS
    input_fields = INPUT_FIELDS
    dt_s = R.DT_S

    def __init__(self, params: Parameters, limits=None, config=None, effects: dict | None = None,
                 partition: str | dict = "fine", **options):
        limit_blas_threads()         # firmware_model.onboard.blas: one BLAS thread (the small eigh is 25x slower with more)
        sensor_cfg = dict(getattr(config, "sensor", None) or {}) if config is not None else {}
        if isinstance(limits, Limits):
            lim = limits
        else:
            path = limits if limits is not None else sensor_cfg.get("limits")
            if path is not None and config is not None and not str(path).startswith("/") and getattr(
                    config, "origin", "defaults") not in ("defaults", ""):
                from pathlib import Path
                cand = Path(config.origin).parent / path
                path = cand if cand.exists() else path
            lim = load_limits(path, sensor_cfg.get("debounce_s"), sensor_cfg.get("hysteresis_c"))
        oil_mode = options.pop("oil_mode", sensor_cfg.get("oil_mode", "measured"))
        if oil_mode not in ("measured", "model"):
            raise ParameterError(f"sensor.oil_mode = {oil_mode!r} must be 'measured' or 'model'")
        if options.get("ttl_sump", "model") not in ("model", "held"):
            raise ParameterError(f"sensor option ttl_sump = {options['ttl_sump']!r} must be 'model' or 'held'")
        if params.strings.get("cooler.kind") in ("hold", "measured"):
            # a rig: the sump is conditioned from outside (no cooler to model, a constant reading is normal)
            params = _with_cooler(params, "none")
            options.setdefault("oil_frozen_s", math.inf)
        try:
            opts = SensorOptions(oil_mode=oil_mode, **options)
        except TypeError as exc:
            raise ParameterError(f"unknown sensor option: {exc}") from None
        self.params = params
        self.reduced = R.build_reduced(params, partition=partition, effects=effects)
        self.effects = R.make_effects({k: v for k, v in (effects or {}).items() if k in R.EFFECT_HOOKS})
        self.sp = SensorParams(self.reduced, lim, self.effects, opts, HeldInputSolver(self.reduced.n,
                                                                                     self.reduced.C_j_per_k))
        self.limits = lim
        self.options = opts

    # -- state

    @property
    def nodes(self) -> tuple:
        return self.reduced.nodes

    def initial_state(self, T_oil_c=None, snapshot=None, elapsed_s: float = 0.0, n_vehicles: int | None = None,
                      ambient_c: float | None = None) -> SensorState:
        """Start: every node at the measured oil temperature (NaN/None: ``options.initial_temp_c``, else the ambient
        boundary), or from a snapshot (a SensorState, or the bytes/str/dict of :meth:`snapshot`) cooled down for
        ``elapsed_s`` with the engine off. With both a snapshot and a measured oil: the measurement wins when the
        cooled snapshot's sump is more than 10 K off (then every node starts at it), else it replaces the sump."""
        rp = self.reduced
        if snapshot is not None:
            st = self._restore(snapshot)
            amb = ambient_c
            if amb is None:
                a = np.asarray(st.hold[..., I_AMB], dtype=float)
                amb = float(a.reshape(-1)[0]) if np.all(np.isfinite(a)) else float(rp.bc_default_c[rp.i_ambient])
            T = np.array(st.T_c, dtype=float, copy=True)
            if elapsed_s and elapsed_s > 0:
                for v in np.ndindex(T.shape[:-2]):
                    for c in (MAIN, TWIN):
                        T[v + (c,)] = cool_down(self.sp, T[v + (c,)], float(elapsed_s), amb)
            if T_oil_c is not None and np.all(np.isfinite(np.asarray(T_oil_c, dtype=float))):
                meas = np.broadcast_to(np.asarray(T_oil_c, dtype=float), T.shape[:-2])
                off = np.abs(T[..., MAIN, rp.i_oil] - meas) > 10.0
                T = np.where(off[..., None, None], meas[..., None, None], T)
                T[..., :, rp.i_oil] = meas[..., None]
            B = T.shape[:-2]
            return st._replace(T_c=T, t_last_s=np.full(B, np.nan), age_s=np.where(
                elapsed_s > 0, np.maximum(st.age_s, elapsed_s), st.age_s),
                ttl_s=np.full(B + (N_PUB,), np.nan), k=np.zeros(B, dtype=np.int64))
        B = () if n_vehicles is None else (int(n_vehicles),)
        T0 = np.asarray(np.nan if T_oil_c is None else T_oil_c, dtype=float)
        default = self.options.initial_temp_c
        if default is None:
            default = float(rp.bc_default_c[rp.i_ambient]) if ambient_c is None else float(ambient_c)
        T0 = np.where(np.isfinite(T0), T0, default)
        T0 = np.broadcast_to(T0, B).astype(float)
        n = rp.n
        T = np.broadcast_to(T0[..., None, None], B + (2, n)).copy()
        hold = np.full(B + (8,), np.nan)
        hold[..., I_SPEED] = 0.0
        hold[..., I_TORQUE] = 0.0
        hold[..., I_GEAR] = 0.0
        hold[..., I_OIL] = T0
        return SensorState(
            T_c=T, lag_w=np.zeros(B + (R.N_SRC,)), hold=hold, age_s=np.full(B + (8,), 0.0),
            same_s=np.zeros(B + (8,)), raw_prev=np.full(B + (8,), np.nan), oil_ref_c=np.array(T0, dtype=float),
            level=np.zeros(B + (N_PUB,), dtype=np.int8), pending_s=np.zeros(B + (N_PUB,)),
            ttl_s=np.full(B + (N_PUB,), np.nan), t_last_s=np.full(B, np.nan), k=np.zeros(B, dtype=np.int64),
            rejects=np.zeros(B + (NR,), dtype=np.int64))

    def step(self, state: SensorState, inputs: SensorInputs):
        return step(state, inputs, self.sp)

    def step_deferred(self, state: SensorState, inputs: SensorInputs):
        """``(state, outputs, job)``: the step without the time-to-limit refresh; call :meth:`refresh_ttl` before
        the next step (same outputs as :meth:`step`, bit for bit)."""
        return step_deferred(state, inputs, self.sp)

    @staticmethod
    def refresh_ttl(state: SensorState, job) -> SensorState:
        return refresh_ttl(state, job)

    # -- snapshots

    def snapshot(self, state: SensorState) -> bytes:
        """Serialise a state (JSON, UTF-8): restorable with ``initial_state(snapshot=...)``, also across processes."""
        doc = {"schema": SNAPSHOT_SCHEMA, "variant": self.reduced.variant, "partition": self.reduced.partition,
               "nodes": list(self.reduced.nodes)}
        for name, arr in state._asdict().items():
            a = np.asarray(arr)
            doc[name] = {"dtype": str(a.dtype), "shape": list(a.shape),
                         "data": base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")}
        return json.dumps(doc, separators=(",", ":")).encode("utf-8")

    def _restore(self, snap) -> SensorState:
        if isinstance(snap, SensorState):
            return snap
        if isinstance(snap, (bytes, bytearray, str)):
            try:
                snap = json.loads(snap)
            except (ValueError, UnicodeDecodeError) as exc:
                raise InputError(f"snapshot is not valid JSON: {exc}") from None
        if not isinstance(snap, dict) or snap.get("schema") != SNAPSHOT_SCHEMA:
            raise InputError(f"snapshot schema must be {SNAPSHOT_SCHEMA!r}")
        if snap.get("nodes") != list(self.reduced.nodes):
            raise InputError("snapshot was taken with another thermal network (its node list differs)")
        vals = {}
        for name in SensorState._fields:
            d = snap.get(name)
            if not isinstance(d, dict):
                raise InputError(f"snapshot field {name!r} is missing")
            try:
                a = np.frombuffer(base64.b64decode(d["data"]), dtype=np.dtype(d["dtype"])).reshape(d["shape"])
            except (KeyError, ValueError, TypeError) as exc:
                raise InputError(f"snapshot field {name!r} cannot be decoded: {exc}") from None
            vals[name] = a.copy()
        if not np.all(np.isfinite(vals["T_c"])):
            raise InputError("snapshot temperatures are not all finite")
        return SensorState(**vals)

    # -- figures

    def state_bytes(self, dtype=np.float32) -> int:
        """Bytes of one vehicle's state as an ECU would hold it (floats as ``dtype``, levels 1 byte, counters and
        the step count 4 bytes)."""
        st = self.initial_state(T_oil_c=40.0)
        fb = np.dtype(dtype).itemsize
        total = 0
        for name, a in st._asdict().items():
            a = np.asarray(a)
            if name == "level":
                total += a.size
            elif name in ("rejects", "k"):
                total += 4 * a.size
            else:
                total += fb * a.size
        return total


def _with_cooler(params: Parameters, kind: str) -> Parameters:
    p = Parameters(params.variant, dict(params.values), dict(params.sources), dict(params.units),
                   dict(params.strings), params.origin)
    p.strings["cooler.kind"] = kind
    return p
