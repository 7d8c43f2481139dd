"""Time to limit: how long until each published component reaches its warning limit if the current inputs are held.

Every ``ttl_period_s`` the step leaves a :class:`TtlJob` (one :class:`TtlPoint` per vehicle due: the state after
the step and the operating point it used); :func:`refresh_ttl` solves it after the step's outputs are out. The
held-input network is linear (:func:`held_system`: K from the step's conductances, the cooler linearised, the
oil-system inlet following a modelled sump), and the first crossing of each limit comes from marching it
(:func:`firmware_model.onboard.held_march.march_time_to_limit`: steady state, TR-BDF2 on a geometric grid, no
eigen-decomposition; the compiled kernel runs the same method). With the sump modelled the sump warms or cools
under the held load, and the losses, the oil-side conductances and the cooler move with it: the march re-linearises
the system along its own trajectory as the sump moves (:func:`_point_at`, held_march.Relinearise; docs/sensor.md).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.components import PUBLISHED
from firmware_model.onboard import reduce as R
from firmware_model.onboard.conductance_bins import LN_SPEED_BIN, OIL_BIN_C, SPEED_BIN_MIN_RAD_S
from firmware_model.physics.conductance_matrix import conductance_matrix
from firmware_model.onboard.held_inputs import cooler_slope_w_per_k
from firmware_model.physics.cooler import INLET_DROP_MAX_K, inlet_drop_k
from firmware_model.onboard.held_march import HeldSystem, March, Relinearise, march_time_to_limit
from firmware_model.onboard.params import SensorParams, vehicle_value
from firmware_model.onboard.records import I_AMB, I_COOL, I_RET, I_TORQUE, I_VKMH, N_PUB, SensorState
from firmware_model.onboard.step_cache import StepCache

#: the coupled held system must keep 1 - e_sump^T K^-1 u above this (else a real mode grows: the inlet is frozen)
COUPLING_MARGIN = 1.0e-6
#: with the sump modelled: the oil-system inlet follows the sump through the linearised cooler in the held-input
#: system (a non-symmetric coupling, general eigen-decomposition; docs/sensor.md), unless the step clips it
TTL_INLET_COUPLING = True
#: the published sump's column
I_PUB_OIL = PUBLISHED.index("oil")


class TtlPoint(NamedTuple):
    """One vehicle's state after a step and the operating point the step used: what the time to limit holds."""
    T_main_c: np.ndarray           # (n,) main copy after the step [degC]
    src_w: np.ndarray              # (ns,) heat of every loss source (before the lag) [W]
    G_w_per_k: np.ndarray          # (nl,) link conductances (the step's bin)
    G_streams_w_per_k: np.ndarray  # (nst,) oil-system stream conductances
    dT_in_k: float                 # inlet drop of the main copy [K]
    Q_cool_w: float                # cooler heat of the main copy [W]
    measured: bool                 # the main copy's sump was the measured oil
    row: int                       # gear row (gear - GEAR_MIN)
    omega_in_rad_s: float          # input speed
    T_oil_c: float                 # the main copy's sump at the step [degC]
    T_bc_c: np.ndarray             # (nb,) boundary temperatures [degC]
    used: np.ndarray               # (8,) the inputs the step used (INPUT_FIELDS order)
    rho_cp_j_per_m3k: float        # oil volumetric heat capacity at T_oil_c


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
    ttl_s: np.ndarray        # (28,) time to limit per published component [s]
    march: March | None      # the march (None: no finite steady state, "not available")


def refresh_ttl(state: SensorState, job: TtlJob | None, sp: SensorParams, cache: StepCache) -> SensorState:
    """Run the time-to-limit refresh a step left (``job`` from the step; None: nothing due)."""
    if job is None:
        return state
    ttl = np.array(state.ttl_s, dtype=float, copy=True)
    for v, point in zip(job.vehicles, job.points):
        ttl[v] = time_to_limit(sp, cache, point, v)
    return state._replace(ttl_s=ttl)


def time_to_limit(sp: SensorParams, cache: StepCache, p: TtlPoint, vehicle=None) -> np.ndarray:
    """Time [s] until each published component reaches its warning limit if the current inputs are held.

    With the sump modelled (``ttl_sump = "model"``) and one set of effects, the march re-linearises the held system
    along its own trajectory as the sump warms or cools (:func:`_point_at`, held_march.Relinearise)."""
    return _solve(sp, cache, p, vehicle).ttl_s


def _point_at(sp: SensorParams, cache: StepCache, p: TtlPoint, T_op_c: float, vehicle=None) -> TtlPoint:
    """The held operating point re-evaluated at the sump temperature T_op: the losses (the oil's viscosity), the
    oil-side conductances (their bin), the oil's heat capacity, the cooler's heat and the inlet drop there (as the
    step computes them at a sump of T_op); the state and the inputs are the point's."""
    rp, h, e = sp.reduced, sp.helpers, sp.effects
    x, prop, _ = R.oil_row(rp, T_op_c, h)
    rho_cp_j_per_m3k = float(prop[R.P_RHO] * prop[R.P_CP])
    w = p.omega_in_rad_s
    retarder_w = float(e.retarder_frac) * float(p.used[I_RET]) * abs(float(rp.speed_coef[p.row, 3])) * w
    src_w = R.heat_sources(rp, p.row, w, abs(float(p.used[I_TORQUE])), prop, x, e.src_scale, e.churn_scale,
                           e.needle_scale, retarder_w, h)
    bins = cache.bins.get(sp, p.row, *_bin_centre(w, T_op_c))
    Q_cool_w, mcp_w_per_k, _ = R.cooler_heat(rp, T_op_c, abs(float(rp.speed_coef[p.row, 1])) * w, w, p.used[I_COOL],
                                             p.used[I_AMB], p.used[I_VKMH], rho_cp_j_per_m3k,
                                             vehicle_value(sp.cooler_scale, vehicle),
                                             vehicle_value(sp.thermostat_offset_c, vehicle))
    return p._replace(src_w=src_w, G_w_per_k=bins.G_w_per_k, G_streams_w_per_k=bins.G_streams_w_per_k,
                      dT_in_k=float(inlet_drop_k(Q_cool_w, mcp_w_per_k)), Q_cool_w=float(Q_cool_w),
                      T_oil_c=float(T_op_c), rho_cp_j_per_m3k=rho_cp_j_per_m3k)


def _bin_centre(omega_in_rad_s: float, T_oil_c: float) -> tuple[float, float]:
    """The conductance bin centre as the time to limit computes it: math.log and math.exp (numpy's differ from them
    in the last bit for a few % of the bins, and a last-bit change of the cached modes can move a crossing by one
    search quantum)."""
    if omega_in_rad_s >= SPEED_BIN_MIN_RAD_S:
        omega_q = math.exp(round(math.log(omega_in_rad_s) / LN_SPEED_BIN) * LN_SPEED_BIN)
    else:
        omega_q = 0.0
    return omega_q, round(T_oil_c / OIL_BIN_C) * OIL_BIN_C


def _inlet_follows_sump(p: TtlPoint, measured: bool, slope_w_per_k: float, mcp_w_per_k: float) -> bool:
    """Whether the held-input system couples the oil-system inlet to the sump: the sump is modelled, the cooler has
    a slope, there is a flow, and the step does not clip the inlet drop (a clipped inlet drop does not follow the
    sump)."""
    return TTL_INLET_COUPLING and not measured and slope_w_per_k != 0 and mcp_w_per_k > 0.0 \
        and abs(p.dT_in_k) < INLET_DROP_MAX_K


def _oil_flow_m3_s(sp: SensorParams, row: int, omega_in_rad_s: float) -> float:
    """Oil-system volume flow [m3/s] at this gear and input speed (the pump turns with the layshaft)."""
    rp = sp.reduced
    return rp.flow_m3_per_rad * abs(float(rp.speed_coef[row, 1])) * omega_in_rad_s


def held_system(sp: SensorParams, p: TtlPoint, measured: bool, vehicle=None) -> tuple[HeldSystem, np.ndarray]:
    """(the held-input system over its free nodes, the free nodes) at the operating point ``p`` (its losses,
    conductances, cooler heat and inlet drop at its sump ``p.T_oil_c``; :func:`_point_at` re-evaluates them at
    another sump), the cooler linearised there: K from the conductances, the inlet coupling when the inlet follows
    the sump (and the coupled system passes the stability test below), b from the heat, the boundaries, the inlet
    drop and a measured sump."""
    rp, h = sp.reduced, sp.helpers
    src_w, G_w_per_k, G_streams_w_per_k = p.src_w, p.G_w_per_k, p.G_streams_w_per_k
    K, _ = conductance_matrix(G_w_per_k, h.topology)
    T_oil_c = p.T_oil_c
    slope_w_per_k = 0.0 if measured else cooler_slope_w_per_k(sp, T_oil_c, p.omega_in_rad_s, p.row, p.used,
                                                              p.rho_cp_j_per_m3k, vehicle)
    mcp_w_per_k = p.rho_cp_j_per_m3k * _oil_flow_m3_s(sp, p.row, p.omega_in_rad_s)
    u = None
    if not measured:
        K[rp.i_oil, rp.i_oil] += slope_w_per_k
        if _inlet_follows_sump(p, measured, slope_w_per_k, mcp_w_per_k):
            # the oil-system inlet follows the sump through the linearised cooler: inlet drop
            # (Q0 + slope (T_sump - T0)) / (mdot cp) moves sv (T_sump - T0) slope / (mdot cp) into the streams
            u = (G_streams_w_per_k @ h.stream_scatter) * (slope_w_per_k / mcp_w_per_k)
            # K - u e^T has det(K) (1 - e^T K^-1 u): at or below 0 a real mode grows; then the inlet is frozen
            try:
                if not 1.0 - float(np.linalg.solve(K, u)[rp.i_oil]) > COUPLING_MARGIN:
                    u = None
            except np.linalg.LinAlgError:     # K singular: no steady state either (the march says not available)
                u = None
    if u is not None:
        # the inlet drop is dT_in at the current sump and follows it (the coupling column): its part at the
        # current sump goes into b
        b_in_w = (G_streams_w_per_k * p.dT_in_k) @ h.stream_scatter - u * T_oil_c
    else:
        b_in_w = (G_streams_w_per_k * p.dT_in_k) @ h.stream_scatter      # the inlet drop frozen
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


def _solve(sp: SensorParams, cache: StepCache, p: TtlPoint, vehicle=None) -> _Solution:
    """The held-input system at the step's operating point (:func:`held_system`), marched
    (firmware_model.onboard.held_march); with the sump modelled and one set of effects, re-linearised along the
    march's trajectory at the sump it reaches (:func:`_point_at`)."""
    rp, h = sp.reduced, sp.helpers
    measured = p.measured and sp.options.ttl_sump != "model"   # "model": the sump heats with the held load
    system, free = held_system(sp, p, measured, vehicle)
    pub_free, rows = (h.pub_free_meas, h.pub_rows_meas) if measured else (h.pub_free_all, h.pub_rows_all)
    warning_c = sp.limits.warning_c
    relin = None
    if sp.options.ttl_sump == "model" and sp.scalar_effects:
        def build(T_op_c: float) -> HeldSystem:
            return held_system(sp, _point_at(sp, cache, p, T_op_c, vehicle), False, vehicle)[0]
        relin = Relinearise(rp.i_oil, p.T_oil_c, build)
    march = march_time_to_limit(system, p.T_main_c[free], rows, warning_c[pub_free], relin)
    if march is None:
        return _Solution(np.full(N_PUB, np.nan), None)
    out = np.full(N_PUB, np.inf)
    out[pub_free] = march.ttl_s
    if measured:
        out[I_PUB_OIL] = 0.0 if p.T_oil_c >= warning_c[I_PUB_OIL] else np.inf
    return _Solution(out, march)
