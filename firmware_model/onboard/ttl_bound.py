"""Time to limit with the losses following the warming sump (``ttl_method = "bound"``; docs/sensor.md).

Today's method (:func:`firmware_model.onboard.time_to_limit.time_to_limit`, ``ttl_method = "march"``, the default)
takes the losses, the cooler and the conductances at one sump temperature, the one predicted at the first crossing.
While the sump warms from cold the oil is more viscous at first and the losses are higher than there, and the
cooler's thermostat is still closed, so the components warm faster than predicted: late, or "never". This method
keeps the held system linear and lets the heat of every loss source and the cooler follow the sump along their
chords between the current sump T0 and the far sump T_far:

    q(T_sump) = q(T_far) + beta (T_sump - T_far),  beta = (q(T0) - q(T_far)) / (T0 - T_far)

(q: the sources' heat on the nodes; the cooler likewise, through its slope). beta enters A as one more column on
the sump (``A - beta e_sump^T``, merged with the oil-inlet coupling: one Sherman-Morrison column in the kernel).
T_far is the fixed point of the chord system's steady sump (secant method, at most TTL_BOUND_ITERS steady solves),
so the steady state is the held system's own. Two chord systems are marched (firmware_model.onboard.held_march):
with the step's conductances (right for the fast components, which cross while the sump is still near T0) and with
those of T_far's bin (right for the slow ones); the earlier crossing is kept, so the second march closes a
component once it passes the first's crossing (``stop_s``). Both march on a coarser grid than today's
(TTL_BOUND_RATIO) and close their rows with weights ``B w = C`` (:func:`positive_weights`). Where that is within
TTL_BOUND_GATE_S, today's method runs too and the earlier is kept, so that no early warning comes later than
today's. The compiled kernel (``ttl_refresh_bound`` in gvs_kernel.c, from ``gvs_ttl_refresh`` when the tables'
``ttl_bound`` is set) runs the same steps; it finds T_far from one factorisation of K (every trial's steady sump by
Sherman-Morrison, ``bound_steady_sump``) and solves the chord systems' march by the sump's row (``held_t.by_row``).
"""

from __future__ import annotations

import math

import numpy as np

from firmware_model.onboard import evaluate as E
from firmware_model.onboard.conductance_bins import LN_SPEED_BIN, OIL_BIN_C
from firmware_model.onboard.held_march import HeldSystem, march_time_to_limit
from firmware_model.onboard.kernel_interface import (
    COUPLING_MARGIN,
    MARCH_RATIO,
    TTL_BOUND_GATE_S,
    TTL_BOUND_ITERS,
    TTL_BOUND_RATIO,
    TTL_BOUND_TOL_K,
)
from firmware_model.onboard.params import SensorParams, vehicle_value
from firmware_model.onboard.records import I_AMB, I_COOL, I_VKMH, SensorState
from firmware_model.onboard.step_cache import StepCache
from firmware_model.onboard.time_to_limit import TtlJob, TtlPoint, held_system, loss_heat_w, time_to_limit


def time_to_limit_bound(sp: SensorParams, cache: StepCache, p: TtlPoint, vehicle=None) -> np.ndarray:
    """Time [s] until each published component reaches its warning limit with the inputs held, the losses and the
    cooler following the sump along their chords to the far sump, the earlier of the two chord systems (the
    conductances at the step's sump and at the far sump's bin; module doc). A settled sump, a measured sump held
    (``ttl_sump = "held"``) or per-vehicle effects: the step's own held system, marched once."""
    h = sp.helpers
    measured = p.measured and sp.options.ttl_sump != "model"
    pub_free, rows = (h.pub_free_meas, h.pub_rows_meas) if measured else (h.pub_free_all, h.pub_rows_all)
    warning_c = sp.limits.warning_c
    system, free = held_system(sp, p, p.src_w, p.G_w_per_k, p.G_streams_w_per_k, p.T_oil_c, measured, vehicle)
    systems = [system]
    if not measured and sp.scalar_effects:
        systems = chord_systems(sp, cache, p, system, vehicle)
    ttl_s = None
    ratio = TTL_BOUND_RATIO if len(systems) == 2 else MARCH_RATIO
    for sys_ in systems:
        # the second march only looks for crossings before the first's (the earlier is kept)
        march = march_time_to_limit(sys_, p.T_main_c[free], rows, warning_c[pub_free], stop_s=ttl_s, ratio=ratio)
        if march is not None:
            ttl_s = march.ttl_s if ttl_s is None else np.minimum(ttl_s, march.ttl_s)
    if ttl_s is None:
        out = np.full(len(sp.reduced.published), np.nan)
    else:
        out = np.full(len(sp.reduced.published), np.inf)
        out[pub_free] = ttl_s
        if measured:
            oil = sp.reduced.published_index == sp.reduced.i_oil  # the published sump's column (if published)
            out[oil] = np.where(p.T_oil_c >= warning_c[oil], 0.0, np.inf)
    if np.any(out <= TTL_BOUND_GATE_S):
        # a crossing soon: today's method too, the earlier of the two (no warning later than today's)
        today = time_to_limit(sp, cache, p, vehicle)
        out = np.where(today < out, today, out)
    return out


def chord_systems(sp: SensorParams, cache: StepCache, p: TtlPoint, system: HeldSystem, vehicle=None) -> list:
    """The chord systems from the step's sump T0 to the far sump T_far: [with the step's conductances, with those
    of T_far's bin]; [``system``] (the step's own) when the sump is settled or T_far cannot be found. T_far is the
    fixed point S(T_far) = T_far of the first chord system's steady sump, by the secant method from T0 (where
    S(T0) is the steady sump of the step's own system), at most TTL_BOUND_ITERS chord systems, within the oil
    tables' range."""
    rp = sp.reduced
    T0_c = p.T_oil_c
    q0_w = p.src_w @ rp.src_matrix
    t_prev, g_prev = T0_c, _steady_sump_c(system, rp.i_oil) - T0_c
    if not abs(g_prev) >= TTL_BOUND_TOL_K:
        return [system]
    T_far_c = _clip_oil_c(T0_c + g_prev)
    found = None
    for _ in range(TTL_BOUND_ITERS):
        if abs(T_far_c - T0_c) < TTL_BOUND_TOL_K:
            break
        src_w = loss_heat_w(sp, p, T_far_c)
        beta_w_per_k = (q0_w - src_w @ rp.src_matrix) / (T0_c - T_far_c)
        slope_w_per_k = cooler_chord_slope(sp, p, T_far_c, vehicle)
        base, _ = held_system(sp, p, src_w, p.G_w_per_k, p.G_streams_w_per_k, T0_c, False, vehicle, slope_w_per_k)
        chord = chord_system(base, beta_w_per_k, T_far_c, rp.i_oil)
        g = _steady_sump_c(chord, rp.i_oil) - T_far_c
        if not math.isfinite(g):
            break  # no finite steady state there: the last chord that has one
        found = (T_far_c, src_w, beta_w_per_k, slope_w_per_k, chord)
        if not abs(g) >= TTL_BOUND_TOL_K or g == g_prev:
            break
        t_prev, g_prev, T_far_c = T_far_c, g, _clip_oil_c(T_far_c - g * (T_far_c - t_prev) / (g - g_prev))
    if found is None:
        return [system]
    T_far_c, src_w, beta_w_per_k, slope_w_per_k, chord = found
    bins = cache.bins.get(sp, p.row, *bin_centre(p.omega_in_rad_s, T_far_c, rp.speed_bin_min_rad_s))
    base, _ = held_system(sp, p, src_w, bins.G_w_per_k, bins.G_streams_w_per_k, T_far_c, False, vehicle, slope_w_per_k)
    return [chord, chord_system(base, beta_w_per_k, T_far_c, rp.i_oil)]


def bin_centre(omega_in_rad_s: float, T_oil_c: float, speed_min_rad_s: float) -> tuple[float, float]:
    """The conductance bin's centre (speed, oil) in math.log and math.exp, as the time to limit and the kernel's
    speed_bin_centre compute it (conductance_bins.quantise's numpy differs in the last bit for a few bins)."""
    w = omega_in_rad_s
    w_q = math.exp(round(math.log(w) / LN_SPEED_BIN) * LN_SPEED_BIN) if w >= speed_min_rad_s else 0.0
    return w_q, round(T_oil_c / OIL_BIN_C) * OIL_BIN_C


def _clip_oil_c(T_c: float) -> float:
    """Within the oil tables' range (the properties are held beyond it)."""
    return min(max(T_c, float(E.T_GRID_C[0])), float(E.T_GRID_C[-1]))


def _steady_sump_c(system: HeldSystem, i_oil: int) -> float:
    """The held system's steady sump [degC] (NaN: no finite steady state)."""
    try:
        T_inf_c = np.linalg.solve(system.A_w_per_k, system.b_w)
    except np.linalg.LinAlgError:
        return math.nan
    T = float(T_inf_c[i_oil])
    return T if math.isfinite(T) else math.nan


def cooler_chord_slope(sp: SensorParams, p: TtlPoint, T_far_c: float, vehicle=None) -> float:
    """The cooler's chord from the step's sump to T_far [W/K]: (Q(T_far) - Q_step) / (T_far - T_step), at least 0
    (firmware_model.onboard.evaluate.cooler_heat with the point's inputs, as held_inputs.cooler_slope_w_per_k)."""
    rp = sp.reduced
    drive = float(E.pump_drive(rp, p.row, p.omega_in_rad_s))
    if rp.cooler_code == E.COOLER_CODES["none"] or drive <= 0.0:
        return 0.0
    Q_far_w, _, _ = E.cooler_heat(
        rp,
        T_far_c,
        drive,
        p.omega_in_rad_s,
        p.used[I_COOL],
        p.used[I_AMB],
        p.used[I_VKMH],
        p.rho_cp_j_per_m3k,
        vehicle_value(sp.effects.cooler_scale, vehicle),
        vehicle_value(sp.effects.thermostat_offset_c, vehicle),
    )
    return max((float(Q_far_w) - p.Q_cool_w) / (T_far_c - p.T_oil_c), 0.0)


def chord_system(base: HeldSystem, beta_w_per_k: np.ndarray, T_far_c: float, i_oil: int) -> HeldSystem:
    """``base`` (all nodes free) with the sources following the sump: ``A - beta e_sump^T``, ``b - beta T_far``.
    The column is left out when it would leave no finite steady state (``1 - e^T A^-1 beta`` at or below
    COUPLING_MARGIN); the maximum principle and the weights are decided again for the new A."""
    A = base.A_w_per_k
    try:
        if not 1.0 - float(np.linalg.solve(A, beta_w_per_k)[i_oil]) > COUPLING_MARGIN:
            return base
    except np.linalg.LinAlgError:
        return base
    A = A.copy()
    A[:, i_oil] -= beta_w_per_k
    b = base.b_w - beta_w_per_k * T_far_c
    off = np.ones(A.shape[0], dtype=bool)
    off[i_oil] = False
    # -A Metzler without a positive row sum: the sump column is the only one that changed
    # (a beta_i <= 0 only raises row i's sum: no positive row sum of -A stays so)
    metzler = bool(base.metzler and np.all(-A[off, i_oil] >= 0.0) and np.all(beta_w_per_k <= 0.0))
    C = base.C_j_per_k
    return HeldSystem(A, C, b, True, metzler, None if metzler else positive_weights(A, C))


def positive_weights(A: np.ndarray, rhs: np.ndarray | None = None) -> np.ndarray | None:
    """w > 0 with B w = rhs (> 0; default 1), B = A's diagonal minus the moduli of its off-diagonal entries (None:
    no such w); the march's weighted bounds (held_march.HeldSystem.weights). Any such w makes the w-weighted max
    norm of the deviation non-increasing; the chord systems take rhs = C (every node's weighted deviation then
    decays at a rate of at least 1/w_i), which closes their rows sooner than rhs = 1 (8.8 instead of 12.2 march
    steps a refresh on bench_kernel.py's drive)."""
    B = -np.abs(A)
    np.fill_diagonal(B, np.diag(A))
    try:
        w = np.linalg.solve(B, np.ones(A.shape[0]) if rhs is None else rhs)
    except np.linalg.LinAlgError:
        return None
    return w if bool(np.all(np.isfinite(w)) and np.all(w > 0.0)) else None


def refresh_ttl(state: SensorState, job: TtlJob | None, sp: SensorParams, cache: StepCache) -> SensorState:
    """Run the time-to-limit refresh a step left (``job`` from the step; None: nothing due) with the sensor's
    ``ttl_method``: "bound" (:func:`time_to_limit_bound`) or "march" (time_to_limit.time_to_limit)."""
    if job is None:
        return state
    solve = time_to_limit_bound if sp.options.ttl_method == "bound" else time_to_limit
    ttl = np.array(state.ttl_s, dtype=float, copy=True)
    for v, point in zip(job.vehicles, job.points):
        ttl[v] = solve(sp, cache, point, v)
    return state._replace(ttl_s=ttl)
