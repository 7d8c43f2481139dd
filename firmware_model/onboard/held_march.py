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
    #: the event (``event``): when the node first reached its temperature [s] (NaN: never within the march) and
    #: every free node's temperature then (the Hermite interpolant of that step); the march stopped there
    event_t_s: float = math.nan
    event_T_c: np.ndarray | None = None


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
    open_: np.ndarray,
    gap_k: np.ndarray,
    rate_max_k_per_s: float,
    w_rows: np.ndarray,
    ratio: float = MARCH_RATIO,
    t_cap_s: float = math.inf,
    t_end_s: float = TTL_HORIZON_S,
) -> tuple[float, float]:
    """The first step's end and the step after it (t_skip, h). With the maximum principle applied to the
    derivative (which obeys the same equation), no node warms faster than ``rate = max_j max(de_j/dt(0), 0)`` at any
    later time, so no open row crosses before ``t_min = min gap / rate``: the first step goes straight to the last
    grid point at or before t_min (the grid after it unchanged). ``rate == 0``: nothing warms now, so nothing ever
    warms and every open row is closed (in place). NaN: no skip. Without the Metzler structure but with weights
    (HeldSystem.weights) row i warms no faster than ``rate w_i``, ``rate = max_j |de_j/dt(0)| / w_j``
    (:func:`_bound_scale`; w_rows: the rows' weights, 1 when Metzler; ratio: the grid's, MARCH_RATIO or the bounded
    method's). ``t_cap_s``: no skip past it (an event's earliest time); ``t_end_s``: the march's horizon."""
    t_skip, h = 0.0, MARCH_H0_S
    if not rate_max_k_per_s > 0.0:
        if rate_max_k_per_s <= 0.0:
            open_[:] = False
        if not t_cap_s < math.inf:
            return t_skip, h
    t_min = t_cap_s
    if open_.any():
        t_min = min(t_min, float(np.min(gap_k[open_] / (rate_max_k_per_s * w_rows[open_]))))
    while t_skip + h <= t_min and t_skip + h < t_end_s:
        t_skip = t_skip + h
        h = h * ratio
    return t_skip, h


def _tr_bdf2(A: np.ndarray, C: np.ndarray, e: np.ndarray, h_step: float) -> np.ndarray | None:
    """One TR-BDF2 step of ``C de/dt = -A e`` (both stages with ``C + d A``); None: singular."""
    d = MARCH_D_FRAC * h_step
    M = np.diag(C) + d * A
    try:
        e_g = np.linalg.solve(M, C * e - d * (A @ e))
        return np.linalg.solve(M, C * (MARCH_A1 * e_g - MARCH_A0 * e))
    except np.linalg.LinAlgError:
        return None


class _Event:
    """A node rising to a temperature (march_time_to_limit's ``event``): open while the bounds let it get there."""

    def __init__(self, sys: HeldSystem, event, T0_c: np.ndarray, T_inf: np.ndarray, e: np.ndarray, bounded: bool):
        self.open, self.bounded, self.j, self.T_c, self.w = False, bounded, 0, 0.0, 1.0
        if event is None:
            return
        self.j, self.T_c = event
        self.w = 1.0 if not bounded or sys.metzler else float(sys.weights[self.j])
        self.open = bool(T0_c[self.j] < self.T_c)
        self.close_unless_reachable(sys, T_inf, e)

    def close_unless_reachable(self, sys: HeldSystem, T_inf: np.ndarray, e: np.ndarray) -> None:
        if self.open and self.bounded:
            self.open = bool(T_inf[self.j] + _bound_scale(sys, e) * self.w >= self.T_c)

    def earliest_s(self, sys: HeldSystem, T0_c: np.ndarray, de: np.ndarray) -> float:
        """No earlier than this [s] (inf: no bound); the event closes when nothing warms now."""
        if not self.open:
            return math.inf
        rate = _bound_scale(sys, de)
        self.open = not rate <= 0.0  # (NaN: open)
        return (self.T_c - T0_c[self.j]) / (rate * self.w) if self.open and rate > 0.0 else math.inf

    def root(self, h_step: float, T_inf, e, de, e_new, de_new) -> float:
        """Where in the step (0..1] the node reaches it (inf: not in this step)."""
        j, T = self.j, self.T_c
        if not self.open or not T_inf[j] + e_new[j] >= T:
            return math.inf
        return _first_root(h_step, T_inf[j] + e[j] - T, de[j], T_inf[j] + e_new[j] - T, de_new[j])


def _cross(open_, out, rows, f0, f1, de, de_new, h_step: float, t_s: float, s_ev: float, watch) -> float:
    """The open rows that reach their limit in the step from t_s (before the event's s_ev) closed with their time in
    ``out``; returns the first watched row's s in the step (inf: none)."""
    s_watch = math.inf
    for i in np.flatnonzero(open_ & (f1 >= 0.0)):
        r = rows[i]
        s = _first_root(h_step, f0[i], de[r], f1[i], de_new[r])
        if s > s_ev:
            continue  # after the event: the next system decides
        out[i] = min(_quantum_ceil(t_s + s * h_step), TTL_HORIZON_S)
        open_[i] = False
        if watch[i] and s < s_watch:
            s_watch = s
    return s_watch


def _start_rows(sys, T0_rows, Tinf_rows, lim, Crow, w_rows, scale, energy, done) -> tuple[np.ndarray, np.ndarray]:
    """(0 for the rows at their limit now, else inf; the rows the bounds leave open) at the march's start (``done``
    rows: inf, never open)."""
    todo = np.ones(T0_rows.size, dtype=bool) if done is None else ~np.asarray(done, dtype=bool)
    out = np.where(todo & (T0_rows >= lim), 0.0, np.inf)
    open_ = todo & (T0_rows < lim)
    if sys.metzler or sys.weights is not None:
        open_ &= Tinf_rows + scale * w_rows >= lim
    if not sys.coupled:
        open_ &= Tinf_rows + np.sqrt(energy / Crow) >= lim
    return out, open_


def march_time_to_limit(
    sys: HeldSystem,
    T0_c: np.ndarray,
    rows: np.ndarray,
    limit_c: np.ndarray,
    watch: np.ndarray | None = None,
    watch_node: int = 0,
    ratio: float = MARCH_RATIO,
    event: tuple[int, float] | None = None,
    t_start_s: float = 0.0,
    done: np.ndarray | None = None,
) -> March | None:
    """First time [s] each free node ``rows`` reaches ``limit_c`` with the inputs held (module doc); None: no finite
    steady state ("not available"). ``watch`` (bool per row): free node ``watch_node``'s temperature at the first
    crossing of a watched row (the re-linearisation's). ``ratio``: the grid's (the bounded method's:
    TTL_BOUND_RATIO). ``event`` (free node, a temperature above its start): the march stops where the node reaches
    it, the rows not crossed by then inf, the state then returned (the bounded method's next part starts there).
    ``t_start_s``: the march's start time (in the times returned). ``done`` (bool per row): decided, never open."""
    A, C, b = sys.A_w_per_k, sys.C_j_per_k, sys.b_w
    try:
        T_inf = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(T_inf)):
        return None
    e = T0_c - T_inf
    de = -(A @ e) / C
    T0_rows, lim, Tinf_rows, Crow = T0_c[rows], limit_c, T_inf[rows], C[rows]
    energy = float(np.sum(C * e * e))
    bounded = sys.metzler or sys.weights is not None
    w_rows = np.ones(rows.size) if sys.metzler or sys.weights is None else sys.weights[rows]
    scale = _bound_scale(sys, e) if bounded else 0.0
    out, open_ = _start_rows(sys, T0_rows, Tinf_rows, lim, Crow, w_rows, scale, energy, done)
    out[np.isfinite(out)] = _quantum_ceil(t_start_s)
    watch = np.zeros(rows.size, dtype=bool) if watch is None else np.asarray(watch, dtype=bool)
    watch_t, watch_T = math.nan, math.nan
    ev = _Event(sys, event, T0_c, T_inf, e, bounded)
    ev_t, ev_T = math.nan, None
    t, h, t_skip, steps = 0.0, MARCH_H0_S, 0.0, 0
    t_end = TTL_HORIZON_S - t_start_s
    if bounded and (open_.any() or ev.open):
        t_cap = ev.earliest_s(sys, T0_c, de)
        t_skip, h = _skip_to(open_, lim - T0_rows, _bound_scale(sys, de), w_rows, ratio, t_cap, t_end)
    while (open_.any() or ev.open) and t < t_end:
        h_step = t_skip if t_skip > 0.0 else min(h, t_end - t)
        steps += 1
        e_new = _tr_bdf2(A, C, e, h_step)
        if e_new is None:  # singular (as the kernel's failed factorisation): not available
            return None
        de_new = -(A @ e_new) / C
        t_new = t + h_step
        f0 = Tinf_rows + e[rows] - lim
        f1 = Tinf_rows + e_new[rows] - lim
        s_ev = ev.root(h_step, T_inf, e, de, e_new, de_new)
        s_watch = _cross(open_, out, rows, f0, f1, de, de_new, h_step, t_start_s + t, s_ev, watch)
        if s_watch < math.inf and math.isnan(watch_t):
            j = watch_node
            watch_t, watch_T = (
                t + s_watch * h_step,
                float(T_inf[j] + _hermite(s_watch, h_step, e[j], de[j], e_new[j], de_new[j])),
            )
        if s_ev < math.inf:
            ev_t = t_start_s + t + s_ev * h_step
            ev_T = T_inf + _hermite(s_ev, h_step, e, de, e_new, de_new)
            break
        energy_new = float(np.sum(C * e_new * e_new))
        if bounded:
            ev.close_unless_reachable(sys, T_inf, e_new)
            open_ &= Tinf_rows + _bound_scale(sys, e_new) * w_rows >= lim
        if not sys.coupled or energy_new <= energy:
            open_ &= Tinf_rows + np.sqrt(energy_new / Crow) >= lim
        e, de, t, energy = e_new, de_new, t_new, energy_new
        # after the skip's step (the grid's steps up to t_skip) h is already the next one
        h, t_skip = (h if t_skip > 0.0 else h * ratio), 0.0
    return March(out, T_inf, watch_t, watch_T, steps, ev_t, ev_T)
