"""The onboard step: ``step(state, inputs, params, cache) -> (state, outputs)``, one 0.1 s step of the sensor.

Pure: no I/O, no clock, nothing that grows; every array has a fixed shape, and what it memoises lives in the
:class:`~firmware_model.onboard.step_cache.StepCache` it is given (pure functions of their keys: the outputs do not
depend on the cache's contents). One step for every use: one truck is a batch of shape ``()``, a fleet a batch of
shape ``(V,)`` (state from ``initial_state(..., n_vehicles=V)``, input fields arrays of shape (V,)). Forward Euler
at dt = 0.1 s (stability proven when the parameters load, see firmware_model.onboard.stability).

Per step (docs/sensor.md):

1. inputs are checked and repaired (firmware_model.onboard.input_check): hold last good, clamp, or degrade; every
   rejection counted; a forward time jump propagates the state with the inputs held (firmware_model.onboard.
   held_inputs), a backward one skips the step;
2. the operating point: gear, input speed and torque, and the oil temperature: the measured one when it is valid
   (a boundary condition of the network), else the network's own sump;
3. heat of every loss source (compact loss maps), through the first-order heat lag (tau 1 s, exact for a held
   input: the step's average of the lagged heat);
4. conductances of every link at the centre of the operating point's bin (firmware_model.onboard.conductance_bins;
   one vehicle: from the cache), the cooler (seed 3.4, Eq 82-83) and the oil-system inlet drop it causes;
5. one Euler step of two copies of the network side by side: the *main* copy (oil measured when available) whose
   temperatures are published, and the *open-loop twin* whose sump is always integrated with the cooler model;
   ``measured - twin sump`` is the published oil innovation, the live view of the sim-to-real gap;
6. warning levels (two levels, hysteresis, debounce), with the time to limit of the last refresh counted down;
7. every ``ttl_period_s``, the refresh of the time to limit from the new state with the inputs held
   (firmware_model.onboard.time_to_limit): :func:`step` runs it at its end, the CAN service after sending the
   step's frames (:func:`step_deferred`, then ``refresh_ttl``); same outputs either way.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from firmware_model.components import LEVEL_NA, MODE_HOLDING, MODE_NORMAL, MODE_OIL_MODEL
from firmware_model.onboard import evaluate as E
from firmware_model.onboard.conductance_bins import bin_centre, bin_conductances, quantise
from firmware_model.onboard.held_inputs import jump_state
from firmware_model.onboard.input_check import DRIVE_FROZEN_BITS, INPUT_BITS, OIL_FROZEN_BITS, InputCheck, check_inputs
from firmware_model.onboard.kernel_interface import P_CP, P_RHO, RECOVER_MAX_S, TTL_FRESH_S
from firmware_model.onboard.params import SensorParams
from firmware_model.onboard.records import (
    I_AMB,
    I_COOL,
    I_GEAR,
    I_OIL,
    I_RET,
    I_SPEED,
    I_TORQUE,
    I_VKMH,
    MAIN,
    N_INPUTS,
    N_REJECT,
    REJECT_INDEX,
    TWIN,
    SensorInputs,
    SensorOutputs,
    SensorState,
    SensorStatus,
)
from firmware_model.onboard.step_cache import StepCache
from firmware_model.onboard.time_to_limit import TtlJob, TtlPoint
from firmware_model.onboard.ttl_bound import refresh_ttl
from firmware_model.onboard.warning_levels import update_levels
from firmware_model.physics.cooler import inlet_drop_k
from firmware_model.physics.heat_lag import heat_lag_step
from firmware_model.physics.kinematics import GEAR_MIN
from firmware_model.units import RAD_S_PER_RPM

_I_TIME_JUMP, _I_TIME_BACKWARD = REJECT_INDEX["time_jump"], REJECT_INDEX["time_backward"]
#: degraded mode by [drive inputs good, oil measured]
_MODE_OF = np.array([[MODE_HOLDING, MODE_HOLDING], [MODE_OIL_MODEL, MODE_NORMAL]], dtype=np.int8)


class NetworkStep(NamedTuple):
    """The network part of a step (arrays of the batch shape B)."""

    T_c: np.ndarray  # B + (2, n): both copies after the step [degC]
    lag_w: np.ndarray  # B + (ns,): heat-lag state [W]
    src_w: np.ndarray  # B + (ns,): heat of every source this step (before the lag) [W]
    G_w_per_k: np.ndarray  # B + (nl,): link conductances at the bin centre
    G_streams_w_per_k: np.ndarray  # B + (nst,): oil-system stream conductances
    dT_in_k: np.ndarray  # B + (2,): inlet drop of each copy [K]
    Q_cool_w: np.ndarray  # B + (2,): cooler heat of each copy [W]
    T_oil_main_c: np.ndarray  # B: the main copy's sump at the start of the step (measured or modelled)
    T_bc_c: np.ndarray  # B + (nb,): boundary temperatures
    row: np.ndarray  # B: gear row
    omega_in_rad_s: np.ndarray  # B: input speed
    rho_cp_j_per_m3k: np.ndarray  # B: oil volumetric heat capacity at the main sump
    #: B + (2,): the main copy's cooler heat [W] and inlet drop [K] by the cooler's law at its sump, for the time to
    #: limit with the sump modelled; None where the step took the law itself (no measured_cooler = "balance")
    law_main: np.ndarray | None


def step(state: SensorState, inputs: SensorInputs, sp: SensorParams, cache: StepCache | None = None):
    """One 0.1 s step: ``(state, outputs)``; the input state is not modified. ``cache``: the sensor's
    :class:`StepCache` (None: a fresh one, same outputs, slower). Equivalent to :func:`step_deferred` followed by
    ``refresh_ttl``."""
    cache = StepCache() if cache is None else cache
    state, outputs, job = step_deferred(state, inputs, sp, cache)
    return refresh_ttl(state, job, sp, cache), outputs


def step_deferred(state: SensorState, inputs: SensorInputs, sp: SensorParams, cache: StepCache):
    """:func:`step` without its slow part: ``(state, outputs, job)``; ``refresh_ttl(state, job, sp, cache)`` must
    run before the next step (the CAN service runs it after the step's frames are on the bus).

    The time to limit is refreshed every ``ttl_period_s`` from the state *after* a step and published (counted down)
    from the next step on; the outputs of a step never depend on that step's refresh, so deferring it changes when
    the work is done, not a single output bit."""
    B = state.t_last_s.shape
    raw = _raw_inputs(inputs, B)  # B + (8,)
    t_now = np.asarray(inputs.t_s, dtype=float)
    t_now = t_now if t_now.shape == B else np.broadcast_to(t_now, B)
    counts = np.zeros(B + (N_REJECT,), dtype=np.int64)
    if np.isfinite(t_now).any() or state.t_last_s.size == 0:
        gap = t_now - state.t_last_s
        known = np.isfinite(gap)
        reset = known & (gap < -sp.options.clock_reset_s)  # a reset clock: its time is the new base, one step
        backward = known & (gap < 0.5 * sp.dt_s) & ~reset
        jump = known & (gap > 1.5 * sp.dt_s)
        counts[..., _I_TIME_JUMP] = jump
        counts[..., _I_TIME_BACKWARD] = backward | reset
        if backward.all():
            return _skip(state, counts, sp)
        if backward.any():  # some vehicles of a batch only: they keep their state, the others step
            skipped = _skip(state, counts.copy(), sp)[:2]
            new_state, outputs, job = _step_all(state, raw, t_now, counts, jump, gap, sp, cache, backward)
            new_state, outputs = _merge_skipped(skipped, new_state, outputs, backward)
            return new_state, outputs, job
        return _step_all(state, raw, t_now, counts, jump, gap, sp, cache, None)
    return _step_all(state, raw, t_now, counts, None, None, sp, cache, None)


def _step_all(state, raw, t_now, counts, jump, gap, sp: SensorParams, cache: StepCache, skipped):
    """Steps 1-7 for every vehicle (``skipped``: vehicles whose results will be discarded, left out of the
    time-to-limit job)."""
    if jump is not None and jump.any():
        g_s = np.where(jump, gap - sp.dt_s, 0.0)
        state = jump_state(state, g_s, sp, cache, raw[..., I_OIL])._replace(recover_s=jump_recover_s(state, g_s, sp))
    chk = check_inputs(state, raw, sp)
    counts[..., : chk.counts.shape[-1]] = chk.counts
    net = _network_step(state, chk, raw[..., I_OIL], sp, cache)
    return _finish(state, raw, t_now, chk, net, counts, sp, skipped)


def _merge_skipped(skipped, new_state: SensorState, outputs: SensorOutputs, mask: np.ndarray):
    """(state, outputs) with the vehicles of ``mask`` taken from ``skipped`` (their step skipped: time went back)."""

    def pick(a, b):
        a, b = np.asarray(a), np.asarray(b)
        return np.where(mask.reshape(mask.shape + (1,) * (b.ndim - mask.ndim)), a, b)

    st, out = skipped
    return (
        SensorState(*(pick(a, b) for a, b in zip(st, new_state))),
        SensorOutputs(
            pick(out.T_c, outputs.T_c),
            pick(out.level, outputs.level),
            pick(out.ttl_s, outputs.ttl_s),
            SensorStatus(*(pick(a, b) for a, b in zip(out.status, outputs.status))),
        ),
    )


def _raw_inputs(inputs: SensorInputs, B: tuple) -> np.ndarray:
    """The eight input fields as one float array B + (8,)."""
    if B == ():
        try:
            return np.array(inputs[:N_INPUTS], dtype=float)
        except (TypeError, ValueError):
            pass
    return np.stack([np.broadcast_to(np.asarray(inputs[i], dtype=float), B) for i in range(N_INPUTS)], axis=-1)


def _conductances(sp: SensorParams, cache: StepCache, row, omega_in_rad_s, T_oil_c):
    """(G, stream G, G of the node-node links, G of the boundary links) [W/K] at the centre of the operating point's
    bin: from the cache for one vehicle, evaluated for a batch (the same numbers)."""
    h = sp.helpers
    if row.ndim == 0 and sp.scalar_effects:
        return cache.bins.get(
            sp, int(row), *bin_centre(float(omega_in_rad_s), float(T_oil_c), sp.reduced.speed_bin_min_rad_s)
        )
    omega_q, T_q, _ = quantise(omega_in_rad_s, T_oil_c, sp.reduced.speed_bin_min_rad_s)
    G_w_per_k, G_streams_w_per_k = bin_conductances(sp, row, omega_q, T_q)
    return G_w_per_k, G_streams_w_per_k, G_w_per_k[..., h.int_idx], G_w_per_k[..., h.ext_idx]


def _heat_sources_w(sp: SensorParams, used, gear_row, omega_in_rad_s, torque_nm, prop, T_grid_x):
    """Heat of every loss source [W] (B + (ns,)) at the step's operating point, the retarder's from its torque."""
    rp, eff = sp.reduced, sp.effects
    retarder_w = E.retarder_heat_w(rp, gear_row, omega_in_rad_s, used[..., I_RET], eff.retarder_frac)
    return E.heat_sources(
        rp,
        gear_row,
        omega_in_rad_s,
        torque_nm,
        prop,
        T_grid_x,
        eff.src_scale,
        eff.churn_scale,
        eff.needle_scale,
        retarder_w,
        sp.helpers,
    )


def _network_step(state: SensorState, chk: InputCheck, oil_c, sp: SensorParams, cache: StepCache) -> NetworkStep:
    """Steps 2-5 of the module doc: operating point, heat through the lag, conductances, cooler and inlet drop, one
    explicit step of both copies."""
    rp, h = sp.reduced, sp.helpers
    used, measured = chk.used, chk.measured
    # ---- operating point
    omega_in_rad_s = used[..., I_SPEED] * RAD_S_PER_RPM
    torque_nm = np.abs(used[..., I_TORQUE])
    row = used[..., I_GEAR].astype(np.int64) - GEAR_MIN
    T_c = np.array(state.T_c, dtype=float)
    T_oil_main_c = np.where(measured, oil_c, T_c[..., MAIN, rp.i_oil])
    T_c[..., MAIN, rp.i_oil] = T_oil_main_c
    T_grid_x, prop, _ = E.oil_row(rp, T_oil_main_c, h)
    T_bc_c = np.empty(used.shape[:-1] + sp.T_bc_default_c.shape[-1:])
    T_bc_c[...] = sp.T_bc_default_c
    T_bc_c[..., rp.i_ambient] = used[..., I_AMB]
    T_bc_c[..., rp.i_coolant] = used[..., I_COOL]
    # ---- heat (loss maps) through the heat lag (exact step average for a held input)
    src_w = _heat_sources_w(sp, used, row, omega_in_rad_s, torque_nm, prop, T_grid_x)
    lag = heat_lag_step(state.lag_w, src_w, h.heat_lag)
    lag_w = lag.state_w
    q_nodes_w = lag.delivered_w @ rp.src_matrix  # B + (n,)
    # ---- conductances (at the centre of the operating-point bin), cooler, inlet drop of both copies
    G_w_per_k, G_streams_w_per_k, G_int, G_ext = _conductances(sp, cache, row, omega_in_rad_s, T_oil_main_c)
    drive = E.pump_drive(rp, row, omega_in_rad_s)
    rho_cp_j_per_m3k = prop[..., P_RHO] * prop[..., P_CP]
    Q_law_w, Q_cool_w, mcp_w_per_k = _coolers(
        sp, T_c, q_nodes_w, G_int, G_ext, T_bc_c, G_streams_w_per_k, drive, rho_cp_j_per_m3k, chk
    )
    dT_in_k = inlet_drop_k(Q_cool_w, mcp_w_per_k)
    law_main = None
    if Q_law_w is not Q_cool_w:  # a measured sump's balance: the law's kept for the time to limit
        law_main = np.stack([Q_law_w[..., MAIN], inlet_drop_k(Q_law_w, mcp_w_per_k)[..., MAIN]], axis=-1)
    q_copies_w = (
        q_nodes_w[..., None, :] + (G_streams_w_per_k[..., None, :] * dT_in_k[..., :, None]) @ h.stream_scatter
    )  # B + (2, n)
    q_copies_w[..., rp.i_oil] -= Q_cool_w
    # ---- one explicit (forward Euler) step of both copies; copies first, (2, ..., n), so that the per-vehicle
    # conductances broadcast over one leading axis
    batch = T_c.ndim > 2
    T_new_c = E.explicit_step(
        np.moveaxis(T_c, -2, 0) if batch else T_c,
        np.moveaxis(q_copies_w, -2, 0) if batch else q_copies_w,
        G_int,
        G_ext,
        T_bc_c,
        h.ia,
        h.ib,
        h.ea,
        h.eb,
        sp.dt_over_C_s_k_per_j,
        h.B_int,
        h.B_ext,
    )
    T_new_c = np.moveaxis(T_new_c, 0, -2) if batch else T_new_c
    T_new_c[..., MAIN, rp.i_oil] = np.where(measured, oil_c, T_new_c[..., MAIN, rp.i_oil])
    return NetworkStep(
        T_new_c,
        lag_w,
        src_w,
        G_w_per_k,
        G_streams_w_per_k,
        dT_in_k,
        Q_cool_w,
        T_oil_main_c,
        T_bc_c,
        row,
        omega_in_rad_s,
        rho_cp_j_per_m3k,
        law_main,
    )


def _coolers(sp: SensorParams, T_c, q_nodes_w, G_int, G_ext, T_bc_c, G_streams_w_per_k, drive, rho_cp_j_per_m3k, chk):
    """(the cooler's heat net of the heater by its law, the cooler's heat the step takes: B + (2,) each; mdot cp
    B + (1,)) of both copies: the cooler's law at each copy's sump (E.cooler_heat); the step takes the main copy's
    from the sump's balance where it is measured and the description says so (``measured_cooler`` = "balance",
    :func:`_measured_balance`)."""
    rp, used = sp.reduced, chk.used
    Q_cool_w, mcp_w_per_k, hA_w_per_k = E.cooler_heat(
        rp,
        T_c[..., :, rp.i_oil],
        drive[..., None],
        (used[..., I_SPEED] * RAD_S_PER_RPM)[..., None],
        used[..., I_COOL, None],
        used[..., I_AMB, None],
        used[..., I_VKMH, None],
        rho_cp_j_per_m3k[..., None],
        sp.cooler_scale,
        sp.thermostat_offset_c,
    )
    Q_law_w = Q_cool_w
    if sp.helpers.cooler.measured_balance > 0.5:
        Q_cool_w = _measured_balance(
            sp,
            T_c[..., MAIN, :],
            q_nodes_w,
            G_int,
            G_ext,
            T_bc_c,
            G_streams_w_per_k,
            Q_cool_w,
            mcp_w_per_k,
            hA_w_per_k,
            used,
            chk.measured,
        )
    return Q_law_w, Q_cool_w, mcp_w_per_k


def _measured_balance(
    sp, T_main_c, q_nodes_w, G_int, G_ext, T_bc_c, G_streams_w_per_k, Q_cool_w, mcp_w_per_k, hA_w_per_k, used, measured
):
    """Both copies' cooler heat with the main copy's taken from the sump's balance where its sump is measured (the
    description's ``measured_cooler`` = "balance", E.measured_cooler_heat): the sump's gain, its sources and its
    links at the step's start temperatures. C: network_step's balance_heat."""
    rp = sp.reduced
    Q_main_w = E.measured_cooler_heat(
        rp,
        E.sump_gain_w(sp.helpers, rp.i_oil, T_main_c, q_nodes_w, G_int, G_ext, T_bc_c),
        G_streams_w_per_k.sum(axis=-1),
        mcp_w_per_k[..., 0],
        hA_w_per_k[..., 0],
        T_main_c[..., rp.i_oil],
        used[..., I_AMB],
        used[..., I_VKMH],
    )
    out = np.array(Q_cool_w, dtype=float, copy=True)
    out[..., MAIN] = np.where(measured, Q_main_w, out[..., MAIN])
    return out


def _levels(state: SensorState, T_pub_c, available, ttl_now_s, sp: SensorParams):
    """(level, pending_s, resting) after this step. Nothing near a limit (every vehicle available, every level
    normal, no timer running, every component below warning - hysteresis, no early warning due): the state machine
    rests (every level normal, no timer), the result of :func:`update_levels` without the work."""
    lim = sp.limits
    if (
        available.all()
        and (T_pub_c < sp.warning_rest_c).all()
        and not (state.level.any() or state.pending_s.any())
        and (lim.lead_s <= 0 or ttl_now_s.min() > 2.0 * lim.lead_s)
    ):
        return np.zeros(T_pub_c.shape, dtype=np.int8), np.zeros(T_pub_c.shape), True
    return (*update_levels(state.level, state.pending_s, T_pub_c, available, lim, sp.dt_s, ttl_now_s), False)


def _ttl_job(state: SensorState, chk: InputCheck, net: NetworkStep, sp: SensorParams, skipped=None) -> TtlJob | None:
    """The time-to-limit refreshes due after this step (after the steps k = 0, every, 2 every...; not for the
    vehicles ``skipped``)."""
    due = state.k % sp.ttl_every == 0
    if skipped is not None:
        due = due & ~skipped
    if not due.any():
        return None
    B = state.t_last_s.shape
    vehicles = tuple(v for v in (np.ndindex(B) if B else [()]) if due[v])
    law = sp.options.ttl_sump == "model" and net.law_main is not None
    points = tuple(
        TtlPoint(
            net.T_c[v][MAIN].copy(),
            net.src_w[v],
            net.G_w_per_k[v],
            net.G_streams_w_per_k[v],
            # the sump modelled ahead (ttl_sump "model"): the cooler's law, whatever the step took for a measured one
            float(net.law_main[v][1] if law else net.dT_in_k[v][MAIN]),
            float(net.law_main[v][0] if law else net.Q_cool_w[v][MAIN]),
            bool(chk.measured[v]),
            int(net.row[v]),
            float(net.omega_in_rad_s[v]),
            float(net.T_oil_main_c[v]),
            net.T_bc_c[v],
            chk.used[v],
            float(net.rho_cp_j_per_m3k[v]),
        )
        for v in vehicles
    )
    return TtlJob(vehicles, points)


def jump_recover_s(state: SensorState, g_s, sp: SensorParams) -> np.ndarray:
    """The levels' wait after a forward jump of ``g_s`` [s] (per vehicle): entered with the engine turning (the held
    speed above 0), the drive inputs were unknown through it, an outage as missing frames are; so the wait grows by
    as much as it went past the hold, at most RECOVER_MAX_S (_finish counts it down). Entered with the engine
    stopped (parked), the jump's engine-off cool-down is what happened: no wait."""
    speed = np.asarray(state.hold[..., I_SPEED], dtype=float)
    running = np.isfinite(speed) & (speed > 0.0)
    past = np.maximum(np.asarray(g_s, dtype=float) - sp.options.hold_s, 0.0)
    return np.where(running & (past > 0.0), np.minimum(state.recover_s + past, RECOVER_MAX_S), state.recover_s)


def _finish(state: SensorState, raw, t_now, chk: InputCheck, net: NetworkStep, counts, sp: SensorParams, skipped=None):
    """Steps 6-7 of the module doc: published temperatures, warnings, time to limit counted down, status, the new
    state and the time-to-limit job."""
    rp, lim, dt = sp.reduced, sp.limits, sp.dt_s
    T_pub_c = net.T_c[..., MAIN, rp.published_index]
    # drive inputs missing past the hold: levels not available, and for as long again (at most RECOVER_MAX_S) once
    # they are back: the parts' temperatures still rest on the held inputs of the outage
    in_hold = chk.drive_age_s <= sp.options.hold_s
    available = in_hold & ~(state.recover_s > 0.5 * dt)
    back_s = np.maximum(state.recover_s - dt, 0.0)
    recover_s = np.where(in_hold, back_s, np.minimum(state.recover_s + dt, RECOVER_MAX_S))
    k = state.k
    steps_since_refresh = np.minimum(k, (k - 1) % sp.ttl_every + 1)  # 0 at k = 0
    ttl_now_s = np.maximum(state.ttl_s - (steps_since_refresh * dt)[..., None], 0.0)
    # the early warning judges only a time to limit refreshed at most TTL_FRESH_S ago (a held replay's coarse step
    # refreshes once per row): an older one is published counted down, but neither raises an early warning nor
    # holds one (it reads as "never"): the levels between refreshes follow the temperatures
    fresh = steps_since_refresh * dt <= TTL_FRESH_S + 0.5 * dt
    ttl_lead_s = np.where(np.asarray(fresh)[..., None], ttl_now_s, np.inf)
    level, pending_s, resting = _levels(state, T_pub_c, available, ttl_lead_s, sp)
    at_limit = T_pub_c >= lim.warning_c
    if not resting and (level.any() or at_limit.any()):
        ttl_out_s = np.where(level == LEVEL_NA, np.nan, np.where(at_limit, 0.0, ttl_now_s))
    else:
        ttl_out_s = ttl_now_s
    measured, ok = chk.measured, chk.ok
    oil_ok = ok[..., I_OIL]
    mode = _MODE_OF[chk.drive_ok.astype(np.intp), measured.astype(np.intp)]
    T_twin_oil_c = net.T_c[..., TWIN, rp.i_oil].copy()
    oil_innovation_c = np.where(oil_ok, raw[..., I_OIL] - T_twin_oil_c, np.nan)
    frozen_bits = (chk.drive_frozen * DRIVE_FROZEN_BITS) | (chk.oil_frozen * OIL_FROZEN_BITS)
    rejects = state.rejects + counts
    # the oil inlet of a forced oil system (the description's derived oil.inlet): the main copy's sump this step
    # took (the measurement when used) minus the cooler's drop it applied to the jets' streams
    oil_inlet_c = net.T_oil_main_c - net.dT_in_k[..., MAIN] if rp.oil_inlet else np.full(net.T_oil_main_c.shape, np.nan)
    status = SensorStatus(
        mode,
        ok[..., I_SPEED],
        ok[..., I_TORQUE],
        ok[..., I_GEAR],
        oil_ok,
        ok @ INPUT_BITS,
        T_twin_oil_c,
        oil_innovation_c,
        (~measured).astype(np.int8),
        frozen_bits,
        rejects,
        oil_inlet_c,
    )
    new_state = SensorState(
        net.T_c,
        net.lag_w,
        np.where(ok, chk.used, state.hold),
        chk.age_s,
        chk.same_s,
        raw,
        chk.oil_ref_c,
        level,
        pending_s,
        state.ttl_s,
        # no frame time (NaN): the step was on the 0.1 s grid, the last time moves on with it
        np.where(np.isfinite(t_now), t_now, state.t_last_s + sp.dt_s),
        state.k + 1,
        rejects,
        recover_s,
    )
    return new_state, SensorOutputs(T_pub_c, level, ttl_out_s, status), _ttl_job(state, chk, net, sp, skipped)


def _skip(state: SensorState, counts, sp: SensorParams):
    """A step whose time went backwards: nothing is integrated; outputs repeat the current state (for every vehicle
    of the batch: :func:`step_deferred` merges them where only some vehicles went back)."""
    rp = sp.reduced
    rejects = state.rejects + counts
    st = state._replace(rejects=rejects)
    B = state.t_last_s.shape
    T_pub = state.T_c[..., MAIN, rp.published_index]
    z = np.zeros(B, dtype=bool)
    status = SensorStatus(
        np.full(B, MODE_HOLDING, dtype=np.int8),
        z,
        z,
        z,
        z,
        np.zeros(B, dtype=np.int64),
        state.T_c[..., TWIN, rp.i_oil],
        np.full(B, np.nan),
        np.ones(B, dtype=np.int8),
        np.zeros(B, dtype=np.int64),
        rejects,
        np.full(B, np.nan),
    )
    return st, SensorOutputs(T_pub, state.level, state.ttl_s, status), None
