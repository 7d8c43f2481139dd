"""The onboard network with its inputs held: the linear system, and what the sensor does with it besides the time to
limit (firmware_model.onboard.time_to_limit): propagate the state over a forward time jump (held inputs, then engine
off) and cool a snapshot down on restart (engine off), both with the exact modal solution
(firmware_model.onboard.held_modes).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.onboard import evaluate as E
from firmware_model.onboard.held_modes import HeldModes, decompose
from firmware_model.onboard.kernel_interface import P_CP, P_RHO
from firmware_model.onboard.params import SensorParams, first_row, first_value, vehicle_value
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
    TWIN,
    SensorState,
)
from firmware_model.onboard.step_cache import StepCache
from firmware_model.physics.conductance_matrix import conductance_matrix
from firmware_model.physics.cooler import heater_heat_w, heater_slope_w_per_k, inlet_drop_k
from firmware_model.physics.kinematics import GEAR_MIN
from firmware_model.units import RAD_S_PER_RPM


class LinearSystem(NamedTuple):
    """``C dT/dt = -K T + b`` over the ``free`` nodes (the others held)."""

    K_w_per_k: np.ndarray  # (n, n)
    b_w: np.ndarray  # (n,)
    free: np.ndarray  # indices of the free nodes


def linear_system(
    sp: SensorParams,
    G_w_per_k,
    q_nodes_w,
    xfer_nodes_w,
    T_bc_c,
    T_oil_c,
    Q_cool_w,
    measured: bool,
    cooler_slope_w_per_k,
) -> LinearSystem:
    """The main network with everything held: a measured sump is held (its links enter b), a modelled one is free
    with the cooler linearised at the current sump (Q = Q0 + slope (T - T0))."""
    rp, h = sp.reduced, sp.helpers
    n = rp.n
    K, G_ext = conductance_matrix(G_w_per_k, h.topology)
    b = q_nodes_w + xfer_nodes_w + np.bincount(h.ea, G_ext * T_bc_c[h.eb], minlength=n)
    if measured:
        free = np.flatnonzero(np.arange(n) != rp.i_oil)
        b = b - K[:, rp.i_oil] * T_oil_c
    else:
        free = np.arange(n)
        K[rp.i_oil, rp.i_oil] += cooler_slope_w_per_k
        b[rp.i_oil] += cooler_slope_w_per_k * T_oil_c - Q_cool_w
    return LinearSystem(K, b, free)


def cooler_slope_w_per_k(
    sp: SensorParams, T_oil_c: float, omega_in_rad_s: float, row: int, used, rho_cp_j_per_m3k: float, vehicle=None
) -> float:
    """dQ_cooler/dT_oil [W/K] at this operating point, the sump heater's taken off (liquid: its hA unless saturated;
    air: a finite difference; no cooler or drive: the heater's alone), from
    firmware_model.onboard.evaluate.cooler_heat; ``used``: the step's inputs (INPUT_FIELDS order); ``vehicle``: the
    batch index whose effects apply (None: the first vehicle's). C: cooler_slope."""
    rp = sp.reduced
    drive = E.pump_drive(rp, row, omega_in_rad_s)
    if rp.cooler_code == E.COOLER_CODES["none"] or drive <= 0.0:
        return heater_slope_w_per_k(rp.helpers.cooler, T_oil_c)
    args = (
        drive,
        omega_in_rad_s,
        used[I_COOL],
        used[I_AMB],
        used[I_VKMH],
        rho_cp_j_per_m3k,
        vehicle_value(sp.effects.cooler_scale, vehicle),
        vehicle_value(sp.effects.thermostat_offset_c, vehicle),
    )
    if rp.cooler_code == E.COOLER_CODES["liquid"]:
        Q, _, hA = E.cooler_heat(rp, T_oil_c, *args)
        c = rp.cooler
        # Q is net of the heater: the liquid cooler's own heat decides its saturation
        Q_cooler = float(Q) + heater_heat_w(rp.helpers.cooler, T_oil_c)
        slope = float(hA) if -c["liquid_Qmax_heat"] < Q_cooler < c["liquid_Qmax_cool"] else 0.0
        return slope + heater_slope_w_per_k(rp.helpers.cooler, T_oil_c)
    Q_hi_w, _, _ = E.cooler_heat(rp, T_oil_c + 0.05, *args)
    Q_lo_w, _, _ = E.cooler_heat(rp, T_oil_c - 0.05, *args)
    return max(float((Q_hi_w - Q_lo_w) / 0.1), 0.0)


def jump_state(state: SensorState, gap_s, sp: SensorParams, cache: StepCache, oil_after_c=None) -> SensorState:
    """Propagate over a forward time jump of ``gap_s`` (per vehicle; <= 0: none): held inputs for up to
    time_jump_hold_s, then engine off. The inputs age by the gap: a value held from before it is no recent good
    value (the oil's jump check and the drive inputs' hold then treat it as old, as the C kernel does). A warning
    level change pending before the gap has been pending through it: its debounce timer counts the gap (else rows
    10 s apart took 10 rows to raise a 1 s debounce, 30 s rows never). A single vehicle's propagation that
    :func:`prepare_jump` did ahead is taken from ``cache.ahead`` (the same bits). ``oil_after_c``: the raw oil
    reading of the step after the jump (per vehicle; None or NaN: none), which anchors the state
    (:func:`anchored_to_reading`)."""
    B = state.t_last_s.shape
    T = np.array(state.T_c, dtype=float, copy=True)
    age = np.array(state.age_s, dtype=float, copy=True)
    pending = np.array(state.pending_s, copy=True)
    for v in np.ndindex(B) if B else [()]:
        g = float(np.asarray(gap_s)[v])
        if g <= 0:
            continue
        age[v] = age[v] + g
        pending[v] = np.where(pending[v] > 0, pending[v] + g, pending[v])
        ahead = cache.ahead.take(cache.ahead.key_of(state, g)) if not B and cache.ahead.key is not None else None
        T[v] = ahead if ahead is not None else _jump_temperatures(state, v, g, sp, cache)
        if oil_after_c is not None:
            oil_c, prev_c = float(np.asarray(oil_after_c, dtype=float)[v]), float(state.raw_prev[v + (I_OIL,)])
            T[v] = anchored_to_reading(T[v], g, oil_c, sp, prev_c, float(state.age_s[v + (I_OIL,)]))
    return state._replace(T_c=T, age_s=age.astype(np.asarray(state.age_s).dtype, copy=False), pending_s=pending)


def anchored_to_reading(
    T_c: np.ndarray,
    gap_s: float,
    oil_c: float,
    sp: SensorParams,
    raw_prev_c: float = math.nan,
    prev_age_s: float = 0.0,
) -> np.ndarray:
    """(2, n) temperatures after a jump of ``gap_s``, anchored to the sump read after it: with the sump measured and
    the jump past the hold (its engine-off cool-down taken), every part of both copies moves by its copy's sump's
    distance from a plausible reading ``oil_c``. The cool-down assumed the gearbox stood still through the gap; the
    reading says what it did (a gearbox that ran through it reads warmer than the cool-down gave; one that stood
    still reads about what it gave, and moves little). A reading equal to the last raw one before the gap
    (``raw_prev_c``) does not anchor: a stuck sensor's value, which the frozen check would reject; nor one within
    ``oil_step_c`` of it when that one was not taken (``prev_age_s``, the oil's age before the gap, above 0): a
    rejected reading going on, which the step check goes on judging. Otherwise ``T_c`` as it is."""
    if sp.options.oil_mode != "measured" or not gap_s > sp.options.time_jump_hold_s:
        return T_c
    if not (math.isfinite(oil_c) and sp.input_lo[I_OIL] <= oil_c <= sp.input_hi[I_OIL]):
        return T_c
    if oil_c == raw_prev_c:  # the value from before the gap again: a stuck reading tells nothing (the frozen check)
        return T_c
    if prev_age_s > 0.0 and abs(oil_c - raw_prev_c) <= sp.options.oil_step_c:  # (False for a NaN raw_prev_c)
        return T_c
    return T_c + (oil_c - T_c[:, sp.reduced.i_oil])[:, None]


def prepare_jump(state: SensorState, gap_s: float, sp: SensorParams, cache: StepCache) -> None:
    """Propagate one vehicle's state over a forward jump of ``gap_s`` now and keep the temperatures in
    ``cache.ahead`` for the step that will see the jump (:func:`jump_state` takes them if nothing it reads has
    changed by then). Changes no state and no output."""
    g = float(gap_s)
    if state.t_last_s.shape or not g > 0:
        return
    cache.ahead.put(cache.ahead.key_of(state, g), _jump_temperatures(state, (), g, sp, cache))


def held_temperatures(state: SensorState, v: tuple, t_s: float, sp: SensorParams) -> np.ndarray:
    """(2, n) temperatures of vehicle ``v`` (both copies) after ``t_s`` seconds with its last good inputs held."""
    T = np.array(state.T_c[v], dtype=float, copy=True)
    for c in (MAIN, TWIN):
        T[c] = _held_propagate(sp, state, v, c, t_s)
    return T


def _jump_temperatures(state: SensorState, v: tuple, g: float, sp: SensorParams, cache: StepCache) -> np.ndarray:
    """(2, n) temperatures of vehicle ``v`` (both copies) after a forward jump of ``g`` seconds."""
    held = min(g, sp.options.time_jump_hold_s)
    T = held_temperatures(state, v, held, sp)
    if g > held:
        amb = float(state.hold[v + (I_AMB,)])
        amb = amb if math.isfinite(amb) else float(sp.reduced.bc_default_c[sp.reduced.i_ambient])
        bc = shutdown_boundaries_c(sp, np.asarray(state.hold[v], dtype=float))
        bc[sp.reduced.i_ambient] = amb
        for c in (MAIN, TWIN):
            T[c] = cool_down(sp, cache, T[c], g - held, amb, bc)
    return T


def _held(hold, i: int, default: float) -> float:
    return float(hold[i]) if math.isfinite(hold[i]) else default


def _held_propagate(sp: SensorParams, state: SensorState, v: tuple, copy: int, t_s: float):
    """Temperatures of one copy after t_s seconds with the last good inputs held (exact modal solution): the main
    copy keeps a measured sump at its last reading, the twin integrates its own."""
    rp, h, e = sp.reduced, sp.helpers, sp.effects
    hold = np.array(state.hold[v], dtype=float)
    T0_c = np.array(state.T_c[v + (copy,)], dtype=float)
    speed_rpm, torque_nm = _held(hold, I_SPEED, 0.0), abs(_held(hold, I_TORQUE, 0.0))
    row = int(_held(hold, I_GEAR, 0.0)) - GEAR_MIN
    T_amb_c, T_cool_c = _held(hold, I_AMB, float(sp.aux_default[0])), _held(hold, I_COOL, float(sp.aux_default[1]))
    v_kmh, retarder_nm = _held(hold, I_VKMH, float(sp.aux_default[2])), abs(_held(hold, I_RET, 0.0))
    omega_in_rad_s = speed_rpm * RAD_S_PER_RPM
    measured = (
        copy == MAIN
        and sp.options.oil_mode == "measured"
        and float(np.asarray(state.age_s)[v + (I_OIL,)]) == 0.0
        and math.isfinite(hold[I_OIL])
    )
    T_oil_c = float(hold[I_OIL]) if measured else float(T0_c[rp.i_oil])
    T0_c[rp.i_oil] = T_oil_c
    T_grid_x, prop, phi = E.oil_row(rp, T_oil_c, h)
    T_bc_c = np.array(np.asarray(sp.T_bc_default_c, dtype=float).reshape(-1, sp.reduced.bc_default_c.size)[0])
    T_bc_c[rp.i_ambient], T_bc_c[rp.i_coolant] = T_amb_c, T_cool_c
    retarder_w = E.retarder_heat_w(rp, row, omega_in_rad_s, retarder_nm, first_value(e.retarder_frac))
    src_w = E.heat_sources(
        rp,
        row,
        omega_in_rad_s,
        torque_nm,
        prop,
        T_grid_x,
        first_row(e.src_scale),
        first_value(e.churn_scale),
        first_value(e.needle_scale),
        retarder_w,
        h=h,
    )
    G_w_per_k, G_streams_w_per_k = E.conductances(
        rp, row, omega_in_rad_s, T_grid_x, prop, phi, T0_c, T_bc_c, e if sp.scalar_effects else None, h
    )
    rho_cp_j_per_m3k = float(prop[P_RHO] * prop[P_CP])
    drive = E.pump_drive(rp, row, omega_in_rad_s)
    used = np.array([speed_rpm, torque_nm, row + GEAR_MIN, T_oil_c, T_amb_c, T_cool_c, v_kmh, retarder_nm])
    Q_cool_w, mcp_w_per_k, hA_w_per_k = E.cooler_heat(
        rp,
        T_oil_c,
        drive,
        omega_in_rad_s,
        T_cool_c,
        T_amb_c,
        v_kmh,
        rho_cp_j_per_m3k,
        first_value(e.cooler_scale),
        first_value(e.thermostat_offset_c),
    )
    if measured and h.cooler.measured_balance > 0.5:
        # the cooler from the sump's balance at the start of the hold, held with the inputs (as the step's would be)
        q_nodes_w = src_w @ rp.src_matrix
        gain_w = E.sump_gain_w(h, rp.i_oil, T0_c, q_nodes_w, G_w_per_k[h.int_idx], G_w_per_k[h.ext_idx], T_bc_c)
        Q_cool_w = E.measured_cooler_heat(
            rp, gain_w, G_streams_w_per_k.sum(), mcp_w_per_k, hA_w_per_k, T_oil_c, T_amb_c, v_kmh
        )
    dT_in_k = float(inlet_drop_k(Q_cool_w, mcp_w_per_k))
    slope_w_per_k = 0.0 if measured else cooler_slope_w_per_k(sp, T_oil_c, omega_in_rad_s, row, used, rho_cp_j_per_m3k)
    system = linear_system(
        sp,
        G_w_per_k,
        src_w @ rp.src_matrix,
        (G_streams_w_per_k * dT_in_k) @ h.stream_scatter,
        T_bc_c,
        T_oil_c,
        float(Q_cool_w),
        measured,
        slope_w_per_k,
    )
    modes = decompose(system.K_w_per_k, system.free, sp.sqrt_C)
    T_inf_c = modes.steady(system.b_w[system.free])
    out = T0_c.copy()
    out[system.free] = modes.propagate(T0_c[system.free], T_inf_c, t_s)
    return out


def engine_off_modes(sp: SensorParams, cache: StepCache, ambient_c: float) -> HeldModes:
    """Modes of the engine-off network (no heat, no flow, no cooler; conductances at ambient), cached per 0.1 K."""
    key = ("off", round(ambient_c, 1))
    modes = cache.modes.get(key)
    if modes is None:
        system = _engine_off_system(sp, ambient_c, np.full(sp.reduced.bc_default_c.size, float(ambient_c)))
        modes = cache.modes.put(key, decompose(system.K_w_per_k, system.free, sp.sqrt_C))
    return modes


def _engine_off_system(sp: SensorParams, ambient_c: float, T_bc_c) -> LinearSystem:
    rp, h = sp.reduced, sp.helpers
    T_amb_bc_c = np.full(sp.reduced.bc_default_c.size, float(ambient_c))
    T_grid_x, prop, phi = E.oil_row(rp, ambient_c, h)
    G_w_per_k, _ = E.conductances(
        rp, 0 - GEAR_MIN, 0.0, T_grid_x, prop, phi, np.full(rp.n, ambient_c), T_amb_bc_c, None, h
    )
    return linear_system(
        sp, G_w_per_k, np.zeros(rp.n), np.zeros(rp.n), np.asarray(T_bc_c, dtype=float), ambient_c, 0.0, False, 0.0
    )


def cool_down(sp: SensorParams, cache: StepCache, T0_c, elapsed_s: float, ambient_c: float, boundaries_c=None):
    """Node temperatures after ``elapsed_s`` with the engine off: no heat, no flow, no cooler. The boundaries start
    at ``boundaries_c`` (their temperatures when the engine stopped, in reduce.onboard_boundaries order; None: all at
    ambient) and relax to ambient with the engine's cool-down time constant tau (``boundary.engine_off_tau``): the
    engine and its coolant stay hot for a short stop and are at ambient after a night.

    Exact for the linear engine-off network: with e = T - T_amb, ``C de/dt = -K e + K d exp(-t/tau)`` (d: the
    steady excess that the boundaries at shutdown would hold), the particular solution is ``P exp(-t/tau)`` with
    ``(K - C/tau) P = K d``, and ``T(t) = T_amb + P exp(-t/tau) + Phi(t) (T0 - T_amb - P)`` (Phi: every mode)."""
    T0 = np.asarray(T0_c, dtype=float)
    if elapsed_s <= 0:
        return T0.copy()
    modes = engine_off_modes(sp, cache, ambient_c)
    free = modes.free
    amb = np.full(len(free), float(ambient_c))
    out = T0.copy()
    P = np.zeros(len(free))
    tau_s = float(sp.reduced.engine_off_tau_s)
    if boundaries_c is not None and math.isfinite(tau_s) and tau_s > 0:
        system = _engine_off_system(sp, ambient_c, boundaries_c)
        K = system.K_w_per_k[np.ix_(free, free)]
        d = modes.steady(system.b_w[free]) - amb
        C = sp.sqrt_C[free] ** 2
        P = np.linalg.solve(K - np.diag(C / tau_s), K @ d)
    out[free] = modes.propagate(T0[free] - P, amb, float(elapsed_s)) + P * math.exp(-float(elapsed_s) / tau_s)
    return out


def shutdown_boundaries_c(sp: SensorParams, hold) -> np.ndarray:
    """The boundary temperatures (reduce.onboard_boundaries order) the step used when the engine stopped: the
    defaults of the parameter file with the last ambient and coolant readings (``hold``: the state's held inputs of
    one vehicle)."""
    T_bc_c = np.array(np.asarray(sp.T_bc_default_c, dtype=float).reshape(-1, sp.reduced.bc_default_c.size)[0])
    rp = sp.reduced
    T_bc_c[rp.i_ambient] = _held(hold, I_AMB, float(sp.aux_default[0]))
    T_bc_c[rp.i_coolant] = _held(hold, I_COOL, float(sp.aux_default[1]))
    return T_bc_c


def slowest_time_constant_s(sp: SensorParams, cache: StepCache, ambient_c: float = 25.0) -> float:
    """Time constant of the slowest engine-off mode [s] (how fast a parked gearbox forgets)."""
    return float(1.0 / engine_off_modes(sp, cache, ambient_c).lam_per_s.min())
