"""Time to limit by marching the held-input system: no eigen-decomposition, so an ECU can compute it.

With the inputs held the onboard network is linear, ``C dT/dt = -A T + b`` over its free nodes
(firmware_model.onboard.time_to_limit builds A and b). For each published component this module finds the first time
it reaches its warning limit: the steady state ``T_inf = A^-1 b``; the deviation marched with TR-BDF2 on a geometric
grid (MARCH_H0_S growing by MARCH_RATIO up to TTL_HORIZON_S); a crossing located on the cubic Hermite interpolant and
reported as a multiple of TTL_QUANTUM_S; a stop once the maximum-principle, energy or weighted-norm bounds
(:func:`_bound_scale`) show that no open component can cross. The compiled kernel's ``gvs_ttl_refresh``
(firmware_model/onboard/c/gvs_kernel.c) runs the same march with a sparse LDL^T and a Sherman-Morrison correction
where this reference solves densely; the two agree to rounding. docs/sensor.md, "Time to limit", has the method,
its bounds and why they hold.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

# the march's settings are the kernel's too: described once, in kernel_interface (the C header's GVS_MARCH_* ...)
from firmware_model.onboard.kernel_interface import (
    HERMITE_BISECTIONS,
    HERMITE_SAMPLES,
    MARCH_A0,
    MARCH_A1,
    MARCH_D_FRAC,
    MARCH_H0_S,
    MARCH_RATIO,
    TTL_HORIZON_S,
    TTL_QUANTUM_S,
)


def march_grid_s() -> np.ndarray:
    """The march's time grid [s]: 0, then steps of MARCH_H0_S growing by MARCH_RATIO, the last ending at the
    horizon (the same additions as the kernel, in the same order)."""
    t, h, out = 0.0, MARCH_H0_S, [0.0]
    while t < TTL_HORIZON_S:
        h_step = min(h, TTL_HORIZON_S - t)
        t = t + h_step
        out.append(t)
        h = h * MARCH_RATIO
    return np.array(out)


class HeldSystem(NamedTuple):
    """``C dT/dt = -A T + b`` over the free nodes."""

    A_w_per_k: np.ndarray  # (m, m)
    C_j_per_k: np.ndarray  # (m,)
    b_w: np.ndarray  # (m,)
    coupled: bool  # A is not symmetric (the energy rule needs the energy to fall)
    metzler: bool = True  # -A has no negative entry off its diagonal and no positive row sum (max principle)
    #: not Metzler: w > 0 with B w = 1, B = A's diagonal minus the moduli of its off-diagonal entries (None: no such
    #: w); then the w-weighted max norm of every solution never grows (the bounds on |e|, _bound)
    weights: np.ndarray | None = None


class March(NamedTuple):
    """The first crossings, and a node's temperature at the first crossing of the watched rows."""

    ttl_s: np.ndarray  # (r,) per row: 0 at or above the limit now, inf never within the horizon
    T_inf_c: np.ndarray  # (m,) steady state
    watch_t_s: float  # the first crossing (before the quantum) of a watched row; NaN: none crosses
    watch_T_c: float  # the watched node's temperature then (the Hermite interpolant of its step)
    steps: int = 0  # the march's steps (each one factorisation and two solves): its cost


def _hermite(s, h, f0, g0, f1, g1):
    """Cubic Hermite interpolant at s in [0, 1] of values f0, f1 and derivatives g0, g1 over a step h."""
    s2 = s * s
    s3 = s2 * s
    return (
        (2.0 * s3 - 3.0 * s2 + 1.0) * f0
        + (s3 - 2.0 * s2 + s) * h * g0
        + (3.0 * s2 - 2.0 * s3) * f1
        + (s3 - s2) * h * g1
    )


def _first_root(h, f0, g0, f1, g1) -> float:
    """The first s in (0, 1] where the Hermite interpolant reaches 0 (f0 < 0 <= f1): the first of HERMITE_SAMPLES
    samples at or above 0 brackets it, bisection narrows it."""
    lo, hi = 0.0, 1.0
    for j in range(1, HERMITE_SAMPLES + 1):
        s = j / HERMITE_SAMPLES
        if _hermite(s, h, f0, g0, f1, g1) >= 0.0:
            hi = s
            break
        lo = s
    for _ in range(HERMITE_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if _hermite(mid, h, f0, g0, f1, g1) >= 0.0:
            hi = mid
        else:
            lo = mid
    return hi


def _quantum_ceil(t_s: float) -> float:
    return math.ceil(t_s / TTL_QUANTUM_S) * TTL_QUANTUM_S


def _bound_scale(sys: HeldSystem, x: np.ndarray) -> float:
    """``c`` such that no component of a solution ``x`` (the deviation, or its derivative: the same equation)
    exceeds ``c w_i`` at any later time: with -C^-1 A Metzler without a positive row sum ``max_j max(x_j, 0)``
    (the maximum principle, w = 1); else, with the weights w, ``max_j |x_j| / w_j`` (the w-weighted infinity-norm
    logarithmic norm of -C^-1 A is ``max_i -(B w)_i / (C_i w_i) < 0``)."""
    if sys.metzler:
        return max(float(x.max()), 0.0)
    return float(np.max(np.abs(x) / sys.weights))


def _skip_to(
    open_: np.ndarray, gap_k: np.ndarray, rate_max_k_per_s: float, w_rows: np.ndarray, ratio: float = MARCH_RATIO
) -> tuple[float, float]:
    """The first step's end and the step after it (t_skip, h). With the maximum principle applied to the
    derivative (which obeys the same equation), no node warms faster than ``rate = max_j max(de_j/dt(0), 0)`` at any
    later time, so no open row crosses before ``t_min = min gap / rate``: the first step goes straight to the last
    grid point at or before t_min (the grid after it unchanged). ``rate == 0``: nothing warms now, so nothing ever
    warms and every open row is closed (in place). NaN: no skip. Without the Metzler structure but with weights
    (HeldSystem.weights) row i warms no faster than ``rate w_i``, ``rate = max_j |de_j/dt(0)| / w_j``
    (:func:`_bound_scale`; w_rows: the rows' weights, 1 when Metzler; ratio: the grid's, MARCH_RATIO or the bounded
    method's)."""
    t_skip, h = 0.0, MARCH_H0_S
    if not rate_max_k_per_s > 0.0:
        if rate_max_k_per_s <= 0.0:
            open_[:] = False
        return t_skip, h
    t_min = float(np.min(gap_k[open_] / (rate_max_k_per_s * w_rows[open_])))
    while t_skip + h <= t_min and t_skip + h < TTL_HORIZON_S:
        t_skip = t_skip + h
        h = h * ratio
    return t_skip, h


def march_time_to_limit(
    sys: HeldSystem,
    T0_c: np.ndarray,
    rows: np.ndarray,
    limit_c: np.ndarray,
    watch: np.ndarray | None = None,
    watch_node: int = 0,
    stop_s: np.ndarray | None = None,
    ratio: float = MARCH_RATIO,
) -> March | None:
    """First time [s] each free node ``rows`` reaches ``limit_c`` with the inputs held (module doc); None when the
    held system has no finite steady state (the caller publishes "not available"). ``watch`` (bool per row): the
    temperature of free node ``watch_node`` is recorded at the first crossing of a watched row (the time to limit's
    re-linearisation). ``stop_s`` (per row): an earlier crossing is known, so a row closes after the step that
    passes it (inf unless it crossed by then). ``ratio``: the grid's (the bounded method's: TTL_BOUND_RATIO)."""
    A, C, b = sys.A_w_per_k, sys.C_j_per_k, sys.b_w
    try:
        T_inf = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(T_inf)):
        return None
    e = T0_c - T_inf
    de = -(A @ e) / C
    out = np.full(rows.size, np.inf)
    T0_rows = T0_c[rows]
    out[T0_rows >= limit_c] = 0.0
    lim = limit_c
    Tinf_rows = T_inf[rows]
    Crow = C[rows]
    open_ = T0_rows < lim
    energy = float(np.sum(C * e * e))
    bounded = sys.metzler or sys.weights is not None
    w_rows = np.ones(rows.size) if sys.metzler or sys.weights is None else sys.weights[rows]
    if bounded:
        open_ &= Tinf_rows + _bound_scale(sys, e) * w_rows >= lim
    if not sys.coupled:
        open_ &= Tinf_rows + np.sqrt(energy / Crow) >= lim
    watch = np.zeros(rows.size, dtype=bool) if watch is None else np.asarray(watch, dtype=bool)
    watch_t, watch_T = math.nan, math.nan
    t, h, t_skip, steps = 0.0, MARCH_H0_S, 0.0, 0
    if bounded and open_.any():
        t_skip, h = _skip_to(open_, lim - T0_rows, _bound_scale(sys, de), w_rows, ratio)
    while open_.any() and t < TTL_HORIZON_S:
        h_step = t_skip if t_skip > 0.0 else min(h, TTL_HORIZON_S - t)
        d, steps = MARCH_D_FRAC * h_step, steps + 1
        M = np.diag(C) + d * A
        try:
            e_g = np.linalg.solve(M, C * e - d * (A @ e))
            e_new = np.linalg.solve(M, C * (MARCH_A1 * e_g - MARCH_A0 * e))
        except np.linalg.LinAlgError:  # singular (as the kernel's failed factorisation): not available
            return None
        de_new = -(A @ e_new) / C
        t_new = t + h_step
        f0 = Tinf_rows + e[rows] - lim
        f1 = Tinf_rows + e_new[rows] - lim
        s_watch = math.inf
        for i in np.flatnonzero(open_ & (f1 >= 0.0)):
            r = rows[i]
            s = _first_root(h_step, f0[i], de[r], f1[i], de_new[r])
            out[i] = min(_quantum_ceil(t + s * h_step), TTL_HORIZON_S)
            open_[i] = False
            if watch[i] and s < s_watch:
                s_watch = s
        if s_watch < math.inf and math.isnan(watch_t):
            watch_t = t + s_watch * h_step
            j = watch_node
            watch_T = float(T_inf[j] + _hermite(s_watch, h_step, e[j], de[j], e_new[j], de_new[j]))
        energy_new = float(np.sum(C * e_new * e_new))
        if bounded:
            open_ &= Tinf_rows + _bound_scale(sys, e_new) * w_rows >= lim
        if not sys.coupled or energy_new <= energy:
            open_ &= Tinf_rows + np.sqrt(energy_new / Crow) >= lim
        open_ &= ~np.greater_equal(t_new, math.inf if stop_s is None else stop_s)
        e, de, t, energy = e_new, de_new, t_new, energy_new
        if t_skip > 0.0:
            t_skip = 0.0  # the skip's step was the grid's steps up to t_skip: h is the next one
        else:
            h = h * ratio
    return March(out, T_inf, watch_t, watch_T, steps)
