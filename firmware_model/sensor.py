"""The onboard virtual temperature sensor: a pure fixed-step core over the onboard network (firmware_model.reduced).

    sensor = VirtualSensor(load_parameters("GRS905"))
    state = sensor.initial_state(T_oil_c=62.0)
    state, out = sensor.step(state, SensorInputs(1300.0, 2000.0, 9, 62.1, 20.0, 85.0, 40.0, 0.0))
    out.T_c, out.level, out.ttl_s, out.status.degraded_mode

``step(state, inputs, params) -> (state, outputs)`` is pure: no I/O, no clock, nothing that grows; every array has
a fixed shape. The same function serves the live CAN service, offline replay and a fleet batch: give it a state of
shape ``(n_vehicles, ...)`` (``initial_state(..., n_vehicles=V)``) and input fields that are arrays of shape (V,).
Step: dt = 0.1 s, forward Euler (stability proven when the parameters load, see firmware_model.reduced).

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
6. warning levels (two levels, hysteresis, debounce) and, every ``ttl_period_s``, the time to limit with the
   inputs held (exact modal solution of the frozen linear network, firmware_model.overheat).
"""
from __future__ import annotations

import base64
import json
import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from . import reduced as R
from .components import PUBLISHED
from .errors import InputError, ParameterError
from .kinematics import GEAR_MAX, GEAR_MIN
from .network import BOUNDARIES
from .overheat import (LEVEL_NA, LEVEL_NORMAL, HeldInputSolver, Limits, load_limits, update_levels)
from .parameters import Parameters

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
    time_jump_hold_s: float = 60.0       # forward jumps: held inputs this long, then engine off
    ttl_speed_bin_rpm: float = 50.0      # operating-point quantisation of the cached held-input modes
    ttl_oil_bin_c: float = 2.0
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
    gcache: dict = field(compare=False, repr=False, default_factory=dict)

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
_LN_BIN = math.log1p(SPEED_BIN_REL)


def quantise(w_in, T_oil_c):
    """Bin centres of the operating point at which the conductances are evaluated: the conductances are then a pure
    function of (gear, speed bin, oil bin), cached per bin for one vehicle and recomputed for a batch (same values)."""
    w = np.asarray(w_in, dtype=float)
    b = np.round(np.log(np.maximum(w, SPEED_BIN_MIN_RAD_S)) / _LN_BIN)
    w_q = np.where(w >= SPEED_BIN_MIN_RAD_S, np.exp(b * _LN_BIN), 0.0)
    T_q = np.round(np.asarray(T_oil_c, dtype=float) / OIL_BIN_C) * OIL_BIN_C
    return w_q, T_q, b


def _conductances_q(sp: SensorParams, row, w_in, T_oil, h):
    """(G without radiation, stream G) at the quantised operating point; cached for a single vehicle."""
    rp = sp.reduced
    w_q, T_q, b = quantise(w_in, T_oil)
    eff = sp.effects
    if np.ndim(row) == 0:
        key = (int(row), float(b) if w_q > 0 else -1e9, float(T_q))
        cache = sp.gcache
        item = cache.get(key)
        if item is None:
            x, prop, phi = R.oil_row(rp, T_q, h)
            item = R.conductances(rp, row, w_q, x, prop, phi, None, None, eff, h, radiation=False)
            cache[key] = item
            if len(cache) > 1024:
                cache.pop(next(iter(cache)))
        return item
    x, prop, phi = R.oil_row(rp, T_q, h)
    return R.conductances(rp, row, w_q, x, prop, phi, None, None, eff, h, radiation=False)


def step(state: SensorState, inputs: SensorInputs, sp: SensorParams):
    """One 0.1 s step. Pure: returns the new state and the outputs; the input state is not modified."""
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

    # ---- conductances (quantised operating point, radiation exact), cooler, inlet drop
    Gq, Gs = _conductances_q(sp, row, w_in, T_main_oil, h)
    G = np.array(Gq, dtype=float)
    if rp.rad_link.size:
        G[..., rp.rad_link] = R.radiation_conductances(rp, T[..., MAIN, :], T_bc, h)
    T_oils = T[..., :, rp.i_oil]                                                 # B + (2,)
    w_ls = np.abs(rp.speed_coef[row, 1]) * w_in
    rho_cp = prop[..., R.P_RHO] * prop[..., R.P_CP]
    Q_cool, mcp, _ = R.cooler_heat(rp, T_oils, w_ls[..., None], w_in[..., None], used[..., I_COOL, None],
                                   used[..., I_AMB, None], used[..., I_VKMH, None], rho_cp[..., None],
                                   sp.cooler_scale, sp.thermostat_offset)
    dT_in = np.minimum(np.maximum(np.where(mcp > 0, Q_cool / np.where(mcp > 0, mcp, 1.0), 0.0), -30.0), 30.0)
    q2 = q[..., None, :] + (Gs[..., None, :] * dT_in[..., :, None]) @ h.stream_scatter            # B + (2, n)
    q2[..., rp.i_oil] -= Q_cool

    # ---- one explicit (forward Euler) step of both copies
    Gi = G[..., None, h.int_idx]
    Ge = G[..., None, h.ext_idx]
    rate = (Gi * (T[..., h.ia] - T[..., h.ib])) @ h.B_int + (Ge * (T[..., h.ea] - T_bc[..., None, h.eb])) @ h.B_ext
    T_new = T + sp.dt_inv_C * (rate + q2)
    T_new[..., MAIN, rp.i_oil] = np.where(measured, oil, T_new[..., MAIN, rp.i_oil])

    # ---- outputs, warnings, time to limit
    T_pub = T_new[..., MAIN, rp.published_index]
    available = drive_age <= opt.hold_s
    level, pend = update_levels(state.level, state.pending_s, T_pub, available, lim, dt)
    ttl = state.ttl_s
    due = (state.k % sp.ttl_every) == 0
    if due.any():
        ttl = np.array(ttl, dtype=float, copy=True)
        for v in (np.ndindex(B) if B else [()]):
            if not due[v]:
                continue
            ttl[v] = _time_to_limit(sp, T_new[v][MAIN], src[v], G[v], Gs[v], float(dT_in[v][MAIN]),
                                    float(Q_cool[v][MAIN]), bool(measured[v]), int(row[v]), float(w_in[v]),
                                    float(T_main_oil[v]), T_bc[v], used[v], float(rho_cp[v]))
    ttl_out = np.where(level == LEVEL_NA, np.nan, np.where(T_pub >= lim.warning_c, 0.0, ttl))
    mode = np.where(~drive_ok, MODE_HOLDING, np.where(measured, MODE_NORMAL, MODE_OIL_MODEL)).astype(np.int8)
    twin_new = T_new[..., TWIN, rp.i_oil]
    innov = np.where(oil_ok, oil - twin_new, np.nan)
    frozen_bits = (drive_frozen * ((1 << I_SPEED) | (1 << I_TORQUE))) | (oil_frozen * (1 << I_OIL))
    rejects = state.rejects + counts
    status = SensorStatus(mode, ok[..., I_SPEED], ok[..., I_TORQUE], ok[..., I_GEAR], oil_ok, ok @ _BITS,
                          twin_new, innov, (~measured).astype(np.int8), frozen_bits, rejects)
    new_state = SensorState(T_new, lag, np.where(ok, used, hold), age, same, raw, oil_ref, level, pend, ttl,
                            np.where(np.isfinite(t_now), t_now, state.t_last_s), state.k + 1, rejects)
    return new_state, SensorOutputs(T_pub, level, ttl_out, status)


_BITS = (1 << np.arange(8)).astype(np.int64)


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
        return st, SensorOutputs(T_pub, state.level, state.ttl_s, status)
    raise InputError("time went backwards for some vehicles of a batch only; step the batch on one time grid")


# ---------------------------------------------------------------------------------------------------------------
# held inputs: linear system, time to limit, time jumps, cool-down


def _linear_system(sp: SensorParams, G, q_nodes, xfer_nodes, T_bc, T_oil_c, Q_cool, measured, cooler_slope):
    """(K, b, free) of C dT/dt = -K T + b for the main network with everything held."""
    rp = sp.reduced
    h = R.helpers(rp)
    n = rp.n
    Gi = G[h.int_idx]
    K = np.zeros((n, n))
    np.add.at(K, (h.ia, h.ia), Gi)
    np.add.at(K, (h.ib, h.ib), Gi)
    np.add.at(K, (h.ia, h.ib), -Gi)
    np.add.at(K, (h.ib, h.ia), -Gi)
    Ge = G[h.ext_idx]
    np.add.at(K, (h.ea, h.ea), Ge)
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


def _op_key(sp, row, w_in, T_oil_c, measured):
    o = sp.options
    wq = round(w_in / (o.ttl_speed_bin_rpm * R.RPM))
    Tq = round(T_oil_c / o.ttl_oil_bin_c)
    return (row, wq, Tq, measured), wq * o.ttl_speed_bin_rpm * R.RPM, Tq * o.ttl_oil_bin_c


def _modes_at(sp, key, w_q, T_q, row, T_bc, measured, used, cooler_slope_fn):
    """Cached modes of the main network at the quantised operating point (pure function of the key)."""
    item = sp.solver.cache.get(key)
    if item is not None:
        sp.solver.cache.move_to_end(key)
        sp.solver.hits += 1
        return item
    rp = sp.reduced
    h = R.helpers(rp)
    x, prop, phi = R.oil_row(rp, T_q, h)
    bc = np.array(rp.bc_default_c, dtype=float)
    Tn = np.full(rp.n, T_q)
    e = sp.effects
    scalar = all(np.ndim(v) == 0 for v in (e.teeth_oil_h, e.housing_air_h, e.planet_oil_h))
    G, _ = R.conductances(rp, row, w_q, x, prop, phi, Tn, bc, e if scalar else None, h)
    slope = cooler_slope_fn(T_q, w_q) if not measured else 0.0
    K, _, free = _linear_system(sp, G, np.zeros(rp.n), np.zeros(rp.n), bc, T_q, 0.0, measured, slope)
    return sp.solver.modes(key, K, free)


def _cooler_slope(sp, T_oil, w_in, row, used, rho_cp):
    rp = sp.reduced
    w_ls = abs(rp.speed_coef[row, 1]) * w_in
    args = (w_ls, w_in, used[I_COOL], used[I_AMB], used[I_VKMH], rho_cp, _scalar(sp.effects.cooler_scale),
            _scalar(sp.effects.thermostat_offset_c))
    q1 = R.cooler_heat(rp, T_oil + 0.05, *args)[0]
    q0 = R.cooler_heat(rp, T_oil - 0.05, *args)[0]
    return max(float((q1 - q0) / 0.1), 0.0)


def _scalar(v):
    a = np.asarray(v, dtype=float)
    return float(a) if a.ndim == 0 else float(a.reshape(-1)[0])


def _time_to_limit(sp, T_main, src, G, Gs, dT_in, Q_cool, measured, row, w_in, T_oil, T_bc, used, rho_cp):
    """Time [s] until each published component reaches its warning limit if the current inputs are held."""
    rp = sp.reduced
    h = R.helpers(rp)
    key, w_q, T_q = _op_key(sp, row, w_in, T_oil, measured)
    slope_fn = (lambda T, w: _cooler_slope(sp, T, w, row, used, rho_cp))
    item = _modes_at(sp, key, w_q, T_q, row, T_bc, measured, used, slope_fn)
    q_nodes = src @ rp.src_matrix
    xfer = (Gs * dT_in) @ h.stream_scatter
    xfer[rp.i_oil] -= Q_cool
    slope = 0.0 if measured else _cooler_slope(sp, T_oil, w_in, row, used, rho_cp)
    # b at the actual operating point (K of the quantised one): sources, boundaries, cooler and inlet drop
    n = rp.n
    Ge = G[h.ext_idx]
    b = q_nodes + xfer + np.bincount(h.ea, Ge * T_bc[h.eb], minlength=n)
    lam, V, s, free = item
    if measured:
        # links to the (held) measured sump enter b
        Gi = G[h.int_idx]
        to_oil = (h.ia == rp.i_oil) | (h.ib == rp.i_oil)
        other = np.where(h.ia[to_oil] == rp.i_oil, h.ib[to_oil], h.ia[to_oil])
        b = b + np.bincount(other, Gi[to_oil] * T_oil, minlength=n)
    else:
        b[rp.i_oil] += slope * T_oil
    b_free = b[free]
    T_inf = HeldInputSolver.steady(item, b_free)
    pos = np.searchsorted(free, rp.published_index)
    pub_free = free[np.minimum(pos, len(free) - 1)] == rp.published_index
    rows = pos[pub_free]
    out = np.full(N_PUB, np.inf)
    out[pub_free] = HeldInputSolver.time_to_limit(item, T_main[free], T_inf, rows, sp.limits.warning_c[pub_free])
    if measured:
        i_pub_oil = PUBLISHED.index("oil")
        out[i_pub_oil] = 0.0 if T_oil >= sp.limits.warning_c[i_pub_oil] else np.inf
    return out


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
    """Temperatures of one copy after t_s seconds with the last good inputs held (exact modal solution)."""
    rp = sp.reduced
    h = R.helpers(rp)
    hold = np.array(state.hold[v], dtype=float)
    T0 = np.array(state.T_c[v + (copy,)], dtype=float)
    spd = hold[I_SPEED] if math.isfinite(hold[I_SPEED]) else 0.0
    gear = int(hold[I_GEAR]) if math.isfinite(hold[I_GEAR]) else 0
    tq = abs(hold[I_TORQUE]) if math.isfinite(hold[I_TORQUE]) else 0.0
    row = gear - GEAR_MIN
    w_in = spd * R.RPM
    T_oil = float(T0[rp.i_oil])
    measured = False
    x, prop, phi = R.oil_row(rp, T_oil, h)
    T_bc = np.array(rp.bc_default_c, dtype=float)
    used = np.array([spd, tq, gear, T_oil, _amb(state, v, sp), T_bc[rp.i_coolant], 50.0, 0.0])
    src = R.heat_sources(rp, row, w_in, tq, prop, x, _first(sp.effects.src_scale), h=h)
    G, Gs = R.conductances(rp, row, w_in, x, prop, phi, T0, T_bc, None, h)
    rho_cp = float(prop[R.P_RHO] * prop[R.P_CP])
    w_ls = abs(rp.speed_coef[row, 1]) * w_in
    Q, mcp, _ = R.cooler_heat(rp, T_oil, w_ls, w_in, T_bc[rp.i_coolant], used[I_AMB], 50.0, rho_cp)
    dT_in = float(np.clip(Q / mcp, -30, 30)) if mcp > 0 else 0.0
    q = src @ rp.src_matrix
    xfer = (Gs * dT_in) @ h.stream_scatter
    slope = _cooler_slope(sp, T_oil, w_in, row, used, rho_cp)
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
    lam, V, s, free = item
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
    ``effects``: {effect id: value or per-vehicle array} for the effects in firmware_model.reduced.EFFECT_HOOKS
    (and oil_level_low, scalar); ``partition``: "fine" (default) or "compact"; ``options``: SensorOptions overrides.
    Raises StabilityError when the parameter set is unsafe for the 0.1 s explicit step.
    """
    Inputs = SensorInputs
    dt_s = R.DT_S

    def __init__(self, params: Parameters, limits=None, config=None, effects: dict | None = None,
                 partition: str | dict = "fine", **options):
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
        try:
            opts = SensorOptions(oil_mode=oil_mode, **options)
        except TypeError as exc:
            raise ParameterError(f"unknown sensor option: {exc}") from None
        if params.strings.get("cooler.kind") in ("hold", "measured"):
            params = _with_cooler(params, "none")
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
