"""Time to limit with the losses following the warming sump (``ttl_method = "bound"``; docs/sensor.md).

The march alone (:func:`firmware_model.onboard.time_to_limit.time_to_limit`, ``ttl_method = "march"``; the default
until 2026-12-04) takes the losses, the cooler and the conductances at one sump temperature, the one predicted at
the first crossing. While the sump warms from cold the oil is more viscous at first and the losses are higher than
there, and the cooler's thermostat is still closed, so the components warm faster than predicted: late, or "never".
This method
keeps the held system linear and lets the heat of every loss source follow the sump along its chord between the
current sump T0 and the far sump T_far:

    q(T_sump) = q(T_far) + beta (T_sump - T_far),  beta = (q(T0) - q(T_far)) / (T0 - T_far)

(q: the sources' heat on the nodes). beta enters A as one more column on the sump (``A - beta e_sump^T``, merged
with the oil-inlet coupling: one Sherman-Morrison column in the kernel). T_far is the fixed point of the chord
system's steady sump (secant method, at most TTL_BOUND_ITERS steady solves), so the steady state is the held
system's own. The cooler then follows a line through its heat at T_far that lies at or below its curve at T0 and at
TTL_BOUND_SAMPLES sumps between (:func:`cooler_line`; its chord lay above the convex part of the curve and was late
from cold starts). Two chord systems are marched (firmware_model.onboard.held_march):
with the step's conductances (right for the fast components, which cross while the sump is still near T0) and with
those of T_far's bin (right for the slow ones); the earlier crossing is kept, so the second march closes a
component once it passes the first's crossing (``stop_s``). Both march on a coarser grid than today's
(TTL_BOUND_RATIO) and close their rows with weights ``B w = C`` (:func:`positive_weights`). Where that is within
TTL_BOUND_GATE_S, today's method runs too and the earlier is kept, so that no early warning comes later than
today's. Where the first system's coupled inlet drop (the cooler's slope over mdot cp) passes its clip before the
first crossing, the first system is marched once more with the drop's secant to the sump there, the earlier kept
(:meth:`Chord.clipped_inlet_k_per_k`; a drop growing past 30 K made the inlet too cold: late). The compiled
kernel (``ttl_refresh_bound`` in gvs_kernel.c, from ``gvs_ttl_refresh`` when the tables'
``ttl_bound`` is set) runs the same steps; it finds T_far from one factorisation of K (every trial's steady sump by
Sherman-Morrison, ``bound_steady_sump``) and solves the chord systems' march by the sump's row (``held_t.by_row``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

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
    TTL_BOUND_SAMPLES,
    TTL_BOUND_TOL_K,
)
from firmware_model.onboard.params import SensorParams, vehicle_value
from firmware_model.onboard.records import I_AMB, I_COOL, I_VKMH, SensorState
from firmware_model.onboard.step_cache import StepCache
from firmware_model.onboard.time_to_limit import (
    TtlJob,
    TtlPoint,
    held_system,
    loss_heat_w,
    oil_flow_m3_s,
    time_to_limit,
)
from firmware_model.physics.cooler import INLET_DROP_MAX_K


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
    ratio = TTL_BOUND_RATIO if len(systems) == 3 else MARCH_RATIO
    first = systems[2] if len(systems) == 3 else None
    watch = None if first is None else h.ttl_relin_pub
    T_x_c = math.nan
    for sys_ in systems[:2]:
        # the second march only looks for crossings before the first's (the earlier is kept); each watches the
        # sump at its first crossing
        march = march_time_to_limit(
            sys_, p.T_main_c[free], rows, warning_c[pub_free], watch, sp.reduced.i_oil, ttl_s, ratio
        )
        if march is not None:
            ttl_s = march.ttl_s if ttl_s is None else np.minimum(ttl_s, march.ttl_s)
            if math.isnan(T_x_c):
                T_x_c = march.watch_T_c
    k_in = None if first is None else first.clipped_inlet_k_per_k(sp, T_x_c)
    if k_in is not None:
        # the first system's coupled inlet drop passes its clip before that crossing: the first system once more
        # with the drop's secant to the sump there (Chord.clipped_inlet_k_per_k), the earlier kept
        again_sys = first.system(sp, vehicle, k_in)
        again = march_time_to_limit(again_sys, p.T_main_c[free], rows, warning_c[pub_free], ratio=ratio)
        if again is not None:
            ttl_s = again.ttl_s if ttl_s is None else np.minimum(ttl_s, again.ttl_s)
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
    # the cooler along a line below its curve (cooler_line), not its chord: the point's heat at T0 on that line
    slope_w_per_k, Q0_w = cooler_line(sp, p, T_far_c, vehicle)
    p = p._replace(Q_cool_w=Q0_w)
    first = Chord(p, src_w, beta_w_per_k, T_far_c, slope_w_per_k)
    bins = cache.bins.get(sp, p.row, *bin_centre(p.omega_in_rad_s, T_far_c, rp.speed_bin_min_rad_s))
    G, Gs = bins.G_w_per_k, bins.G_streams_w_per_k
    base, _ = held_system(sp, p, src_w, G, Gs, T_far_c, False, vehicle, slope_w_per_k)
    return [first.system(sp, vehicle), chord_system(base, beta_w_per_k, T_far_c, rp.i_oil), first]


class Chord(NamedTuple):
    """The first chord system's parts (the step's conductances), to build it again with another inlet slope."""

    p: TtlPoint  # the point, its cooler heat on the cooler's line
    src_w: np.ndarray
    beta_w_per_k: np.ndarray
    T_far_c: float
    slope_w_per_k: float

    def system(self, sp: SensorParams, vehicle=None, inlet_k_per_k: float | None = None) -> HeldSystem:
        p = self.p
        base, _ = held_system(
            sp,
            p,
            self.src_w,
            p.G_w_per_k,
            p.G_streams_w_per_k,
            p.T_oil_c,
            False,
            vehicle,
            self.slope_w_per_k,
            inlet_k_per_k,
        )
        return chord_system(base, self.beta_w_per_k, self.T_far_c, sp.reduced.i_oil)

    def clipped_inlet_k_per_k(self, sp: SensorParams, T_x_c: float) -> float | None:
        """The inlet drop's secant from the step's sump to T_x [K/K] when the first system's coupled inlet drop
        (the cooler's slope over mdot cp, from the step's drop) is beyond the step's clip at T_x (else None): the
        line at or under the clipped drop between them, exact at T_x."""
        p = self.p
        mcp = p.rho_cp_j_per_m3k * oil_flow_m3_s(sp, p.row, p.omega_in_rad_s)
        if not mcp > 0.0 or not abs(p.dT_in_k) < INLET_DROP_MAX_K or not T_x_c != p.T_oil_c:
            return None
        d_x = p.dT_in_k + self.slope_w_per_k / mcp * (T_x_c - p.T_oil_c)
        if not abs(d_x) > INLET_DROP_MAX_K:
            return None
        return (min(max(d_x, -INLET_DROP_MAX_K), INLET_DROP_MAX_K) - p.dT_in_k) / (T_x_c - p.T_oil_c)


def cooler_line(sp: SensorParams, p: TtlPoint, T_far_c: float, vehicle=None) -> tuple[float, float]:
    """(slope [W/K], heat at the step's sump T0 [W]) of the cooler line the chord systems march: through the cooler's
    heat at the far sump, at or below its heat at T0 and at TTL_BOUND_SAMPLES sumps evenly between T0 and T_far
    (the secants' extreme; slope at least 0). Below the curve, the sump warms at least as fast as with the true
    cooler. The chord lay above it where the curve is convex, and so was late from cold starts: there the liquid
    cooler heats the oil at its clip (14 kW) until the sump nears the coolant, and the chord took that heating away
    linearly from the start (docs/sensor.md). The far sump's heat, and so the steady state, is unchanged."""
    T0_c = p.T_oil_c
    Q_far_w = cooler_heat_w(sp, p, T_far_c, vehicle)
    d0 = T0_c - T_far_c
    slope_w_per_k = (p.Q_cool_w - Q_far_w) / d0
    for k in range(1, TTL_BOUND_SAMPLES + 1):
        T_c = T0_c + (T_far_c - T0_c) * (k / (TTL_BOUND_SAMPLES + 1))
        sec = (cooler_heat_w(sp, p, T_c, vehicle) - Q_far_w) / (T_c - T_far_c)
        # below the curve at T_c: slope (T_c - T_far) <= Q(T_c) - Q(T_far)
        slope_w_per_k = max(slope_w_per_k, sec) if d0 < 0.0 else min(slope_w_per_k, sec)
    slope_w_per_k = max(slope_w_per_k, 0.0)
    return slope_w_per_k, Q_far_w + slope_w_per_k * d0


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


def cooler_heat_w(sp: SensorParams, p: TtlPoint, T_c: float, vehicle=None) -> float:
    """The cooler's heat [W] at sump T with the point's inputs (0 without a cooler or its drive)."""
    rp = sp.reduced
    drive = float(E.pump_drive(rp, p.row, p.omega_in_rad_s))
    if rp.cooler_code == E.COOLER_CODES["none"] or drive <= 0.0:
        return 0.0
    Q_w, _, _ = E.cooler_heat(
        rp,
        T_c,
        drive,
        p.omega_in_rad_s,
        p.used[I_COOL],
        p.used[I_AMB],
        p.used[I_VKMH],
        p.rho_cp_j_per_m3k,
        vehicle_value(sp.effects.cooler_scale, vehicle),
        vehicle_value(sp.effects.thermostat_offset_c, vehicle),
    )
    return float(Q_w)


def cooler_chord_slope(sp: SensorParams, p: TtlPoint, T_far_c: float, vehicle=None) -> float:
    """The cooler's chord from the step's sump to T_far [W/K]: (Q(T_far) - Q_step) / (T_far - T_step), at least 0
    (firmware_model.onboard.evaluate.cooler_heat with the point's inputs, as held_inputs.cooler_slope_w_per_k)."""
    rp = sp.reduced
    if rp.cooler_code == E.COOLER_CODES["none"] or float(E.pump_drive(rp, p.row, p.omega_in_rad_s)) <= 0.0:
        return 0.0
    return max((cooler_heat_w(sp, p, T_far_c, vehicle) - p.Q_cool_w) / (T_far_c - p.T_oil_c), 0.0)


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
