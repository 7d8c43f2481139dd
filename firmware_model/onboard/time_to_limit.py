"""Time to limit: how long until each published component reaches its warning limit if the current inputs are held.

Every ``ttl_period_s`` the step leaves a :class:`TtlJob` (one :class:`TtlPoint` per vehicle due: the state after
the step and the operating point it used); :func:`refresh_ttl` solves it after the step's outputs are out. The
held-input network is linear (:func:`held_system`: K from the step's conductances, the cooler linearised, the
oil-system inlet following a modelled sump), and the first crossing of each limit comes from marching it
(:func:`firmware_model.onboard.held_march.march_time_to_limit`: steady state, TR-BDF2 on a geometric grid, no
eigen-decomposition; the compiled kernel runs the same method). With the sump modelled the sump warms or cools
under the held load, and the losses and the oil-side conductances move with it: the system is re-linearised at the
sump temperature the previous solution predicts at the earliest crossing (docs/sensor.md).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.onboard import evaluate as E
from firmware_model.onboard.conductance_bins import LN_SPEED_BIN, OIL_BIN_C
from firmware_model.onboard.held_inputs import cooler_slope_w_per_k
from firmware_model.onboard.held_march import HeldSystem, March, march_time_to_limit
from firmware_model.onboard.kernel_interface import (
    COUPLING_MARGIN,
    TTL_RELINEARISE_STEPS,
    TTL_RELINEARISE_TOL_K,
)
from firmware_model.onboard.params import SensorParams
from firmware_model.onboard.records import I_RET, I_TORQUE, SensorState
from firmware_model.onboard.step_cache import StepCache
from firmware_model.physics.conductance_matrix import conductance_matrix
from firmware_model.physics.cooler import INLET_DROP_MAX_K

#: with the sump modelled: the oil-system inlet follows the sump through the linearised cooler in the held-input
#: system (a non-symmetric coupling, general eigen-decomposition; docs/sensor.md), unless the step clips it
TTL_INLET_COUPLING = True


class TtlPoint(NamedTuple):
    """One vehicle's state after a step and the operating point the step used: what the time to limit holds."""

    T_main_c: np.ndarray  # (n,) main copy after the step [degC]
    src_w: np.ndarray  # (ns,) heat of every loss source (before the lag) [W]
    G_w_per_k: np.ndarray  # (nl,) link conductances (the step's bin)
    G_streams_w_per_k: np.ndarray  # (nst,) oil-system stream conductances
    dT_in_k: float  # inlet drop of the main copy [K]
    Q_cool_w: float  # cooler heat of the main copy [W]
    measured: bool  # the main copy's sump was the measured oil
    row: int  # gear row (gear - GEAR_MIN)
    omega_in_rad_s: float  # input speed
    T_oil_c: float  # the main copy's sump at the step [degC]
    T_bc_c: np.ndarray  # (nb,) boundary temperatures [degC]
    used: np.ndarray  # (8,) the inputs the step used (INPUT_FIELDS order)
    rho_cp_j_per_m3k: float  # oil volumetric heat capacity at T_oil_c


class TtlJob:
    """The time-to-limit refreshes a step leaves: the batch index of each vehicle due and its point (and, from the
    compiled core, the kernel's own gvs_ttl_point records, which it refreshes from). ``points`` may be given as a
    function of nothing that makes them: the compiled core's jobs make their TtlPoint tuples only when a numpy
    refresh or a test asks (a batch of 1000 vehicles would otherwise build 1000 of them per refresh, unused)."""

    __slots__ = ("vehicles", "_points", "raw")

    def __init__(self, vehicles: tuple, points, raw: object = None):
        self.vehicles, self._points, self.raw = vehicles, points, raw

    @property
    def points(self) -> tuple:
        if callable(self._points):
            self._points = self._points()
        return self._points

    def __repr__(self) -> str:
        return f"TtlJob({len(self.vehicles)} vehicles{', kernel records' if self.raw is not None else ''})"


class _Solution(NamedTuple):
    ttl_s: np.ndarray  # (28,) time to limit per published component [s]
    march: March | None  # the march (None: no finite steady state, "not available")


def refresh_ttl(state: SensorState, job: TtlJob | None, sp: SensorParams, cache: StepCache) -> SensorState:
    """Run the time-to-limit refresh a step left (``job`` from the step; None: nothing due)."""
    if job is None:
        return state
    ttl = np.array(state.ttl_s, dtype=float, copy=True)
    for v, point in zip(job.vehicles, job.points):
        ttl[v] = time_to_limit(sp, cache, point, v)
    return state._replace(ttl_s=ttl)


def loss_heat_w(sp: SensorParams, p: TtlPoint, T_op_c: float) -> np.ndarray:
    """Heat of every loss source [W] with the point's load at sump temperature T_op (as the step evaluates it)."""
    rp, h, e = sp.reduced, sp.helpers, sp.effects
    x, prop, _ = E.oil_row(rp, T_op_c, h)
    retarder_w = float(E.retarder_heat_w(rp, p.row, p.omega_in_rad_s, float(p.used[I_RET]), float(e.retarder_frac)))
    return E.heat_sources(
        rp,
        p.row,
        p.omega_in_rad_s,
        abs(float(p.used[I_TORQUE])),
        prop,
        x,
        e.src_scale,
        e.churn_scale,
        e.needle_scale,
        retarder_w,
        h,
    )


def time_to_limit(sp: SensorParams, cache: StepCache, p: TtlPoint, vehicle=None) -> np.ndarray:
    """Time [s] until each published component reaches its warning limit if the current inputs are held.

    With the sump modelled (``ttl_sump = "model"``) the system is re-linearised at the sump temperature the
    previous solution predicts at the earliest crossing (from the same state), up to TTL_RELINEARISE_STEPS times."""
    sol = _solve(sp, p, p.src_w, p.G_w_per_k, p.G_streams_w_per_k, p.T_oil_c, vehicle)
    if sp.options.ttl_sump != "model" or not sp.scalar_effects:
        return sol.ttl_s
    T_op_c = p.T_oil_c
    for _ in range(TTL_RELINEARISE_STEPS):
        if sol.march is None or math.isnan(sol.march.watch_T_c):
            break
        T_next_c = sol.march.watch_T_c  # the sump at the earliest crossing of a component (not the sump)
        if abs(T_next_c - T_op_c) < TTL_RELINEARISE_TOL_K:
            break
        T_op_c = T_next_c
        src_op_w = loss_heat_w(sp, p, T_op_c)
        bins = cache.bins.get(sp, p.row, *_bin_centre(p.omega_in_rad_s, T_op_c, sp.reduced.speed_bin_min_rad_s))
        sol = _solve(sp, p, src_op_w, bins.G_w_per_k, bins.G_streams_w_per_k, T_op_c, vehicle)
    return sol.ttl_s


def _bin_centre(omega_in_rad_s: float, T_oil_c: float, speed_min_rad_s: float) -> tuple[float, float]:
    """The conductance bin centre as the time to limit computes it: math.log and math.exp (numpy's differ from them
    in the last bit for a few % of the bins, and a last-bit change of the cached modes can move a crossing by one
    search quantum); below speed_min_rad_s (ReducedParams.speed_bin_min_rad_s) at standstill."""
    if omega_in_rad_s >= speed_min_rad_s:
        omega_q = math.exp(round(math.log(omega_in_rad_s) / LN_SPEED_BIN) * LN_SPEED_BIN)
    else:
        omega_q = 0.0
    return omega_q, round(T_oil_c / OIL_BIN_C) * OIL_BIN_C


def _inlet_follows_sump(
    sp: SensorParams, p: TtlPoint, measured: bool, slope_w_per_k: float, T_op_c: float, inlet_k_per_k=None
) -> bool:
    """Whether the held-input system couples the oil-system inlet to the sump: the sump is modelled, the cooler has
    a slope, and the inlet drop is inside the step's clip both now and, on the linearised cooler (or the bounded
    method's inlet line ``inlet_k_per_k``), at the operating point's sump T_op (a clipped inlet drop does not follow
    the sump)."""
    if not TTL_INLET_COUPLING or measured:
        return False
    mcp = p.rho_cp_j_per_m3k * oil_flow_m3_s(sp, p.row, p.omega_in_rad_s)
    if not mcp > 0.0:
        return False
    if inlet_k_per_k is not None:
        # the bounded method's inlet line: under the clipped drop by construction, followed as it is
        return inlet_k_per_k != 0.0
    if slope_w_per_k == 0 or not abs(p.dT_in_k) < INLET_DROP_MAX_K:
        return False
    return abs((p.Q_cool_w + slope_w_per_k * (T_op_c - p.T_oil_c)) / mcp) < INLET_DROP_MAX_K


def oil_flow_m3_s(sp: SensorParams, row: int, omega_in_rad_s: float) -> float:
    """Oil-system volume flow [m3/s] at this gear and input speed: a shaft pump's turns with its shaft, a motor
    pump's is fixed, or none while the machine stands (evaluate.pump_drive)."""
    rp = sp.reduced
    if rp.pump_code == E.PUMP_CODES["motor"]:
        return rp.pump_flow_m3_s * float(E.pump_drive(rp, row, omega_in_rad_s))
    return rp.flow_m3_per_rad * float(E.shaft_speed_rad_s(rp, row, rp.pump_speed_col, 1.0)) * omega_in_rad_s


def held_system(
    sp: SensorParams,
    p: TtlPoint,
    src_w,
    G_w_per_k,
    G_streams_w_per_k,
    T_op_c: float,
    measured: bool,
    vehicle=None,
    slope_w_per_k: float | None = None,
    inlet_k_per_k: float | None = None,
) -> tuple[HeldSystem, np.ndarray]:
    """(the held-input system over its free nodes, the free nodes) at the operating point's oil temperature T_op
    (losses ``src_w`` and conductances ``G_w_per_k`` given for it), the cooler linearised at the step's sump
    ``p.T_oil_c`` with its slope at T_op (or ``slope_w_per_k`` when given: the bounded method's chord): K from the
    conductances, the inlet coupling when the inlet follows the sump (and the coupled system passes the stability
    test below), b from the heat, the boundaries, the inlet drop and a measured sump. ``inlet_k_per_k``: the inlet
    drop follows the sump along this slope [K/K] from the step's drop (the bounded method's inlet line) instead of
    the cooler's slope over mdot cp."""
    rp, h = sp.reduced, sp.helpers
    K, _ = conductance_matrix(G_w_per_k, h.topology)
    T_oil_c = p.T_oil_c
    if measured:
        slope_w_per_k = 0.0
    elif slope_w_per_k is None:
        slope_w_per_k = cooler_slope_w_per_k(sp, T_op_c, p.omega_in_rad_s, p.row, p.used, p.rho_cp_j_per_m3k, vehicle)
    mcp_w_per_k = p.rho_cp_j_per_m3k * oil_flow_m3_s(sp, p.row, p.omega_in_rad_s)
    u = None
    if not measured:
        K[rp.i_oil, rp.i_oil] += slope_w_per_k
        if _inlet_follows_sump(sp, p, measured, slope_w_per_k, T_op_c, inlet_k_per_k):
            # the oil-system inlet follows the sump through the linearised cooler: inlet drop
            # (Q0 + slope (T_sump - T0)) / (mdot cp) moves sv (T_sump - T0) slope / (mdot cp) into the streams
            k_in = slope_w_per_k / mcp_w_per_k if inlet_k_per_k is None else inlet_k_per_k
            u = (G_streams_w_per_k @ h.stream_scatter) * k_in
            # K - u e^T has det(K) (1 - e^T K^-1 u): at or below 0 a real mode grows; then the inlet is frozen
            try:
                if not 1.0 - float(np.linalg.solve(K, u)[rp.i_oil]) > COUPLING_MARGIN:
                    u = None
            except np.linalg.LinAlgError:  # K singular: no steady state either (the march says not available)
                u = None
    if u is not None:
        # the inlet drop is dT_in at the current sump and follows it (the coupling column): its part at the
        # current sump goes into b
        b_in_w = (G_streams_w_per_k * p.dT_in_k) @ h.stream_scatter - u * T_oil_c
    else:
        # frozen inlet drop, at the operating point's sump T_op through the linearised cooler
        dT_in_k = p.dT_in_k
        if T_op_c != T_oil_c and not measured:
            if inlet_k_per_k is not None:
                dT_lin_k = p.dT_in_k + inlet_k_per_k * (T_op_c - T_oil_c)
            elif mcp_w_per_k > 0.0:
                dT_lin_k = (p.Q_cool_w + slope_w_per_k * (T_op_c - T_oil_c)) / mcp_w_per_k
            else:
                dT_lin_k = 0.0
            dT_in_k = min(max(dT_lin_k, -INLET_DROP_MAX_K), INLET_DROP_MAX_K)
        b_in_w = (G_streams_w_per_k * dT_in_k) @ h.stream_scatter
    b_w = src_w @ rp.src_matrix + b_in_w + np.bincount(h.ea, G_w_per_k[h.ext_idx] * p.T_bc_c[h.eb], minlength=rp.n)
    if measured:
        # links to the (held) measured sump enter b
        b_w = b_w + np.bincount(h.oil_other, G_w_per_k[h.int_idx][h.oil_links] * T_oil_c, minlength=rp.n)
        free = np.flatnonzero(np.arange(rp.n) != rp.i_oil)
    else:
        # cooler linearised at the current sump: Q = Q0 + g (T - T0)
        b_w[rp.i_oil] += slope_w_per_k * T_oil_c - p.Q_cool_w
        free = np.arange(rp.n)
    metzler, weights = True, None
    if u is not None:
        # the maximum principle with the coupling: no negative entry in -A's sump column, no positive row sum of -A
        # (the boundary links, the cooler's slope and -u: K's links add up to zero in every row)
        off = np.flatnonzero(np.arange(rp.n) != rp.i_oil)
        row_sum = np.bincount(h.ea, G_w_per_k[h.ext_idx], minlength=rp.n) - u
        row_sum[rp.i_oil] += slope_w_per_k
        metzler = bool(np.all(-K[off, rp.i_oil] + u[off] >= 0.0) and np.all(row_sum >= 0.0))
        K[:, rp.i_oil] -= u
        if not metzler:
            weights = _weights(K)
    A = K[np.ix_(free, free)]
    return HeldSystem(A, h.C[free], b_w[free], u is not None, metzler, weights), free


def _weights(A: np.ndarray) -> np.ndarray | None:
    """w > 0 with B w = 1, B = A's (signed) diagonal minus the moduli of its off-diagonal entries; None when B is
    singular or w is not positive (held_march.HeldSystem.weights; the kernel solves the same with K's factors and
    Sherman-Morrison, since B differs from K only in the sump's column)."""
    B = -np.abs(A)
    np.fill_diagonal(B, np.diag(A))
    try:
        w = np.linalg.solve(B, np.ones(A.shape[0]))
    except np.linalg.LinAlgError:
        return None
    return w if bool(np.all(np.isfinite(w)) and np.all(w > 0.0)) else None


def _solve(
    sp: SensorParams, p: TtlPoint, src_w, G_w_per_k, G_streams_w_per_k, T_op_c: float, vehicle=None
) -> _Solution:
    """One held-input solution at the operating point's oil temperature T_op (:func:`held_system`), marched
    (firmware_model.onboard.held_march)."""
    rp, h = sp.reduced, sp.helpers
    measured = p.measured and sp.options.ttl_sump != "model"  # "model": the sump heats with the held load
    system, free = held_system(sp, p, src_w, G_w_per_k, G_streams_w_per_k, T_op_c, measured, vehicle)
    pub_free, rows = (h.pub_free_meas, h.pub_rows_meas) if measured else (h.pub_free_all, h.pub_rows_all)
    warning_c = sp.limits.warning_c
    # with the sump modelled every node is free: watch the sump at the first crossing of the other components
    march = march_time_to_limit(
        system, p.T_main_c[free], rows, warning_c[pub_free], None if measured else h.ttl_relin_pub, rp.i_oil
    )
    if march is None:
        return _Solution(np.full(len(rp.published), np.nan), None)
    out = np.full(len(rp.published), np.inf)
    out[pub_free] = march.ttl_s
    if measured:
        oil = rp.published_index == rp.i_oil  # the published sump's column (if published)
        out[oil] = np.where(p.T_oil_c >= warning_c[oil], 0.0, np.inf)
    return _Solution(out, march)
