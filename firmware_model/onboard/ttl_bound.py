"""Time to limit with the losses, the cooler and the inlet drop following the warming sump (``ttl_method =
"bound"``, the default; docs/sensor.md, "Time to limit").

The march alone (:func:`firmware_model.onboard.time_to_limit.time_to_limit`, ``ttl_method = "march"``) takes the
losses, the cooler and the conductances at one sump temperature. While the sump warms from cold the oil is more
viscous at first, the liquid cooler still heats it and the oil-system inlet runs hotter than the sump, so the
components warm faster than predicted there: late, or "never". This method follows the sump's own path instead:

1. the far sump T_far (:func:`far_sump_c`): where the held model's steady sump, with the losses, the cooler's heat and
   the clipped inlet drop taken at the sump it is evaluated at, is that sump (Illinois method in a bracket);
2. the path T0 -> T_far cut into at most TTL_SEG_MAX parts (:func:`cut_path`) where one line per part fits the
   cooler's heat Q(T) and the inlet drop D(T) = clip(Q / mdot cp, +-30 K) (:class:`Curves`): both have kinks (the
   cooler's 14 kW clip, the thermostat, the drop's clip) that a single line missed by kilowatts;
3. per part (:func:`part_system`) one linear held system: the losses along their chord between the part's ends
   (``A - beta e_sump^T``: :func:`chord_system`), the cooler and the inlet drop along lines through their values at
   the part's end and at or under the curves at TTL_SEG_SAMPLES sumps inside it (:func:`part_lines`: the sump and the
   inlet run at least as warm as with the curves, so the prediction errs early), the conductances of the part's start
   (the step's own in the first part);
4. the parts marched one after the other (:func:`march_segments`): each march stops where the sump reaches its part's
   end (held_march's ``event``) and the next starts from that state and time.

Where the result is within TTL_BOUND_GATE_S, today's method runs too and the earlier is kept, so that no early warning
comes later than today's. The compiled kernel (``ttl_refresh_bound`` in gvs_kernel.c, from ``gvs_ttl_refresh`` when
the tables' ``ttl_bound`` is set) runs the same steps: the far sump from one factorisation of K (every trial's steady
sump r.b with r = K^-1 e_sump), the parts' marches solved by the sump's row (``held_t.by_row``).
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numpy as np

from firmware_model.onboard import evaluate as E
from firmware_model.onboard.conductance_bins import LN_SPEED_BIN, OIL_BIN_C
from firmware_model.onboard.held_march import HeldSystem, march_time_to_limit
from firmware_model.onboard.kernel_interface import (
    COUPLING_MARGIN,
    TTL_BOUND_GATE_S,
    TTL_BOUND_RATIO,
    TTL_BOUND_TOL_K,
    TTL_FAR_ITERS,
    TTL_FAR_TOL_K,
    TTL_SEG_GAP_W,
    TTL_SEG_MAX,
    TTL_SEG_SAMPLES,
    TTL_SEG_TIE_W,
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
from firmware_model.physics.cooler import INLET_DROP_MAX_K, heater_heat_w


class Segments(NamedTuple):
    """The sump's path to its far value cut where one line per part fits the curves: the sumps where the parts end
    (T0 first, T_far last) and each part's held system."""

    T_c: list
    systems: list


def time_to_limit_bound(sp: SensorParams, cache: StepCache, p: TtlPoint, vehicle=None) -> np.ndarray:
    """Time [s] until each published component reaches its warning limit with the inputs held, the losses, the
    cooler and the inlet drop following the sump along lines under their curves, part by part of the sump's path to
    its far value (module doc). A settled sump, a measured sump held (``ttl_sump = "held"``), per-vehicle effects or
    no far sump: the step's own held system, marched once."""
    h, rp = sp.helpers, sp.reduced
    measured = p.measured and sp.options.ttl_sump != "model"
    pub_free, rows = (h.pub_free_meas, h.pub_rows_meas) if measured else (h.pub_free_all, h.pub_rows_all)
    warning_c = sp.limits.warning_c
    seg = None if measured or not sp.scalar_effects else segments(sp, cache, p, vehicle)
    if seg is None:
        system, free = held_system(sp, p, p.src_w, p.G_w_per_k, p.G_streams_w_per_k, p.T_oil_c, measured, vehicle)
        march = march_time_to_limit(system, p.T_main_c[free], rows, warning_c[pub_free])
        ttl_s = None if march is None else march.ttl_s
    else:
        ttl_s = march_segments(seg.systems, seg.T_c, p.T_main_c, rows, warning_c[pub_free], rp.i_oil)
    if ttl_s is None:
        out = np.full(len(rp.published), np.nan)
    else:
        out = np.full(len(rp.published), np.inf)
        out[pub_free] = ttl_s
        if measured:
            oil = rp.published_index == rp.i_oil  # the published sump's column (if published)
            out[oil] = np.where(p.T_oil_c >= warning_c[oil], 0.0, np.inf)
    if np.any(out <= TTL_BOUND_GATE_S):
        # a crossing soon: today's method too, the earlier of the two (no warning later than today's)
        today = time_to_limit(sp, cache, p, vehicle)
        out = np.where(today < out, today, out)
    return out


def march_segments(chain: list, T_c: list, T0_c: np.ndarray, rows, limit_c, i_oil: int):
    """The first crossings [s] marching chain[j] from where the sump reached T_c[j] until it reaches T_c[j + 1],
    then the next part's system from that state (None: a part has no finite steady state)."""
    out, T_now_c, t_s = None, T0_c, 0.0
    for j, system in enumerate(chain):
        event = (i_oil, T_c[j + 1]) if j + 1 < len(chain) else None
        done = None if out is None else np.isfinite(out)
        m = march_time_to_limit(
            system, T_now_c, rows, limit_c, ratio=TTL_BOUND_RATIO, event=event, t_start_s=t_s, done=done
        )
        if m is None:
            return None
        out = m.ttl_s if out is None else np.where(np.isfinite(out), out, m.ttl_s)
        if event is None or math.isnan(m.event_t_s):
            break
        T_now_c, t_s = m.event_T_c, m.event_t_s
    return out


def segments(sp: SensorParams, cache: StepCache, p: TtlPoint, vehicle=None) -> Segments | None:
    """The sump's path from the step's T0 to the far sump T_far (:func:`far_sump_c`) cut into at most TTL_SEG_MAX
    parts (:func:`cut_path`), and each part's held system (:func:`part_system`); None when the sump is settled
    (within TTL_BOUND_TOL_K of T_far) or T_far cannot be found."""
    rp = sp.reduced
    mcp = p.rho_cp_j_per_m3k * oil_flow_m3_s(sp, p.row, p.omega_in_rad_s)
    curves = Curves(sp, p, mcp, vehicle)
    T_far_c = far_sump_c(sp, p, curves, vehicle)
    if not abs(T_far_c - p.T_oil_c) >= TTL_BOUND_TOL_K:
        return None
    grid, cuts = cut_path(curves, p.T_oil_c, T_far_c)
    src = [p.src_w] + [loss_heat_w(sp, p, grid[k]) for k in cuts[1:]]
    chain = []
    for j in range(len(cuts) - 1):
        # the conductances at the part's start sump (the step's own in the first part): on the 240 held points of
        # benchmarks/bench_ttl.py those at its end as well (the earlier kept) changed no prediction's class and were
        # late alone
        if j == 0:
            G, Gs = p.G_w_per_k, p.G_streams_w_per_k
        else:
            bins = cache.bins.get(sp, p.row, *bin_centre(p.omega_in_rad_s, grid[cuts[j]], rp.speed_bin_min_rad_s))
            G, Gs = bins.G_w_per_k, bins.G_streams_w_per_k
        chain.append(part_system(sp, p, curves, grid, cuts, src, j, G, Gs, vehicle))
    return Segments([grid[k] for k in cuts], chain)


class Curves:
    """The cooler's heat Q(T) [W] and the clipped inlet drop D(T) = clip(Q / mdot cp, +-30 K) [K] at sump T with the
    point's inputs (the step's own values at its sump), each evaluated once."""

    def __init__(self, sp: SensorParams, p: TtlPoint, mcp_w_per_k: float, vehicle=None):
        self.sp, self.p, self.mcp, self.vehicle = sp, p, mcp_w_per_k, vehicle
        self.memo = {p.T_oil_c: (p.Q_cool_w, p.dT_in_k)}

    def at(self, T_c: float) -> tuple[float, float]:
        if T_c not in self.memo:
            Q = cooler_heat_w(self.sp, self.p, T_c, self.vehicle)
            d = min(max(Q / self.mcp, -INLET_DROP_MAX_K), INLET_DROP_MAX_K) if self.mcp > 0.0 else 0.0
            self.memo[T_c] = (Q, d)
        return self.memo[T_c]


def far_sump_c(sp: SensorParams, p: TtlPoint, curves: Curves, vehicle=None) -> float:
    """The held model's own steady sump [degC]: T with S(T) = T, S the steady sump of the system whose losses,
    cooler heat and inlet drop are those at T (the step's conductances): S(T) - T changes sign between the step's
    sump T0 and S(T0) (within the oil tables' range), and the Illinois method narrows it (at most TTL_FAR_ITERS
    more solves, to TTL_FAR_TOL_K). NaN: no finite steady state."""
    rp = sp.reduced

    def g(T_c):
        Q, d = curves.at(T_c)
        frozen = p._replace(Q_cool_w=Q, dT_in_k=d)
        src = p.src_w if T_c == p.T_oil_c else loss_heat_w(sp, p, T_c)
        system, _ = held_system(sp, frozen, src, p.G_w_per_k, p.G_streams_w_per_k, p.T_oil_c, False, vehicle, 0.0)
        return _steady_sump_c(system, rp.i_oil) - T_c

    a = p.T_oil_c
    ga = g(a)
    if not math.isfinite(ga):
        return math.nan
    b = _clip_oil_c(a + ga)
    gb = g(b) if b != a else 0.0
    if not math.isfinite(gb):
        return math.nan
    if gb * ga > 0.0:
        return b  # beyond the oil tables' range, or no sign change: the end of the range
    # Illinois (regula falsi that halves the stale end's value): g falls through its root once, with kinks
    for _ in range(TTL_FAR_ITERS):
        if not abs(b - a) >= TTL_FAR_TOL_K:
            break
        c = b - gb * (b - a) / (gb - ga)
        gc = g(c)
        if not math.isfinite(gc):
            return math.nan
        if not abs(gc) >= TTL_FAR_TOL_K:
            return c
        if gc * gb < 0.0:
            a, ga = b, gb
        else:
            ga = 0.5 * ga
        b, gb = c, gc
    return b


def cut_path(curves: Curves, T0_c: float, T_far_c: float) -> tuple[list, list]:
    """(the path's samples [degC], the indices of the sumps where its parts end): T0, TTL_SEG_SAMPLES sumps evenly
    between and T_far. The fewest parts (at most TTL_SEG_MAX) whose lines all lie within TTL_SEG_GAP_W of
    the curves (:func:`part_gap_w`), else TTL_SEG_MAX parts with the smallest worst gap: every choice of cuts tried
    (a cut chosen one at a time, the worst part's best first, missed kinks a later cut needed)."""
    n = TTL_SEG_SAMPLES + 1
    grid = [T0_c + (T_far_c - T0_c) * (k / n) for k in range(n)] + [T_far_c]
    if not T_far_c > T0_c:
        return grid, [0, n]  # a cooling sump's path stays one part (the parts' events are the sump rising)
    gap = {}

    def g(a, b):
        if (a, b) not in gap:
            gap[(a, b)] = part_gap_w(curves, grid, a, b)
        return gap[(a, b)]

    best = ([0, n], g(0, n))
    for m in range(1, TTL_SEG_MAX):
        if not best[1] > TTL_SEG_GAP_W:
            break
        # every m cuts, in order; the first within TTL_SEG_TIE_W of the least worst gap (no tie by rounding)
        combos = [[0, *c, n] for c in itertools.combinations(range(1, n), m)]
        worst = [max(g(a, b) for a, b in zip(c[:-1], c[1:])) for c in combos]
        k = next(i for i, w in enumerate(worst) if w <= min(worst) + TTL_SEG_TIE_W)
        best = (combos[k], worst[k])
    return grid, best[0]


def part_gap_w(curves: Curves, grid: list, a: int, b: int) -> float:
    """How far the part's lines lie under the curves at its samples, at most [W]: the cooler's gap plus the inlet
    drop's times mdot cp."""
    (sq, q_a), (sd, d_a) = part_lines(curves, grid, a, b)
    gap_w = 0.0
    for k in range(a, b):
        Q, d = curves.at(grid[k])
        x = grid[k] - grid[a]
        gap_w = max(gap_w, (Q - q_a - sq * x) + curves.mcp * (d - d_a - sd * x))
    return gap_w


def part_lines(curves: Curves, grid: list, a: int, b: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """((slope [W/K], value at grid[a] [W]) of the cooler's line, (slope [K/K], value [K]) of the inlet drop's) for the
    part grid[a]..grid[b]: through the curve at its end, at or under it at every sample from its start (the
    secants' extreme): along the path the sump and the inlet are at least as warm as with the curves."""
    T_b = grid[b]
    ends = curves.at(T_b)
    out = []
    for i in (0, 1):
        slope = math.nan
        for k in range(a, b):
            sec = (curves.at(grid[k])[i] - ends[i]) / (grid[k] - T_b)
            # under the curve at grid[k]: slope (T_k - T_b) <= f(T_k) - f(T_b)
            slope = sec if math.isnan(slope) else (max(slope, sec) if grid[k] < T_b else min(slope, sec))
        out.append((slope, ends[i] + slope * (grid[a] - T_b)))
    return out[0], out[1]


def part_system(sp, p: TtlPoint, curves: Curves, grid, cuts, src: list, j: int, G, Gs, vehicle=None) -> HeldSystem:
    """Part j's held system (the sump from grid[cuts[j]] to grid[cuts[j + 1]]): the losses along their chord between
    the ends, the cooler and the inlet drop along lines under their curves at TTL_SEG_SAMPLES sumps evenly inside
    the part (:func:`part_lines`; the cooler's slope at least 0), every node free."""
    rp = sp.reduced
    T_a, T_b = grid[cuts[j]], grid[cuts[j + 1]]
    n = TTL_SEG_SAMPLES + 1
    fine = [T_a + (T_b - T_a) * (k / n) for k in range(n)] + [T_b]
    (sq, q_a), (sd, d_a) = part_lines(curves, fine, 0, n)
    beta_w_per_k = (src[j] @ rp.src_matrix - src[j + 1] @ rp.src_matrix) / (T_a - T_b)
    start = p._replace(T_oil_c=T_a, Q_cool_w=q_a, dT_in_k=d_a)
    base, _ = held_system(sp, start, src[j + 1], G, Gs, T_a, False, vehicle, max(sq, 0.0), sd)
    return chord_system(base, beta_w_per_k, T_b, rp.i_oil)


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
    """The cooler's heat [W] at sump T with the point's inputs, net of the sump heater's (without a cooler or its
    drive: the heater's alone, negative). C: bound_cooler_heat."""
    rp = sp.reduced
    drive = float(E.pump_drive(rp, p.row, p.omega_in_rad_s))
    if rp.cooler_code == E.COOLER_CODES["none"] or drive <= 0.0:
        return -float(heater_heat_w(rp.helpers.cooler, T_c))
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
