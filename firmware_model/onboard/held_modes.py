"""Modal solution of the onboard network with its inputs held, and the first-crossing search of the time to limit.

With the inputs frozen the onboard network is linear, ``C dT/dt = -K T + b``. ``K`` is symmetric (a weighted
Laplacian plus boundary and cooler terms on its diagonal), so ``C^-1/2 K C^-1/2 = V diag(lambda) V^T`` with real
``lambda > 0`` and ``T(t) = T_inf + C^-1/2 V exp(-lambda t) V^T C^1/2 (T(0) - T_inf)`` exactly. With the sump
modelled, the oil-system inlet follows the sump through a column ``u`` (``K - u e_sump^T``, not symmetric): then
``V diag(lambda) V^-1`` from a general eigen-decomposition, possibly with a complex pair (temperatures are the real
parts). :func:`decompose` returns a :class:`HeldModes` record; it depends only on the operating point (gear, speed,
oil temperature, oil measured or not, the cooler slope), so callers keep it in a :class:`ModeCache` (a bounded LRU
owned by the sensor's step cache) per quantised operating point; ``T_inf`` and the modal coefficients are recomputed
from the current temperatures and heat every time. Time to limit is the first crossing of the warning limit, found
on a geometric time grid and refined by a safeguarded Newton search on multiples of 2^-7 s
(:meth:`HeldModes.time_to_limit`); the same solution propagates the state over a time jump (held inputs) and cools a
snapshot down (engine off) on restart (firmware_model.onboard.held_inputs).
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

#: geometric time grid of the first-crossing search [s]
TTL_GRID_S = np.concatenate([[0.0], np.geomspace(0.5, 2.0e6, 72)])
#: safeguarded Newton steps of the first-crossing search (from regula falsi on the grid bracket; the bracket halves
#: whenever Newton would leave it)
NEWTON_STEPS = 8
#: the search works on multiples of this [s] and returns the first multiple at or after the crossing: its result
#: rests on comparisons (T >= limit at a multiple), not on the last bits of exp(), so machines whose exp() differs
#: in the last bit (numpy's AVX-512 and AVX2 paths: the vcan VM and its host) give the same time to limit
TTL_QUANTUM_S = 2.0 ** -7
#: time to limit beyond this is reported as never (inf) [s]
TTL_HORIZON_S = float(TTL_GRID_S[-1])
#: held-input decompositions a ModeCache keeps
MODE_CACHE_SIZE = 64


class Coupling(NamedTuple):
    """A node that drives others through a column: ``C dT/dt = -(K - u e_node^T) T + b``."""
    u_w_per_k: np.ndarray      # (n,) the column u [W/K]
    node: int                  # the driving node (the modelled sump)


def _re(x):
    """Real part of a modal sum (the modes of a coupled system may include a complex pair); real input as is."""
    return x.real if np.iscomplexobj(x) else x


@dataclass(frozen=True, eq=False)
class HeldModes:
    """Modes of ``C dT/dt = -K T + b`` over the free nodes, in the coordinates ``C^1/2 T``."""
    lam_per_s: np.ndarray          # (m,) eigenvalues [1/s] (a complex pair possible when coupled)
    V: np.ndarray                  # (m, m) eigenvectors (columns)
    sqrt_C: np.ndarray             # (m,) C^1/2 of the free nodes [sqrt(J/K)]
    free: np.ndarray               # indices of the free nodes in the network
    decay_grid: np.ndarray         # (m, len(TTL_GRID_S)) exp(-lambda t) on the search grid
    V_inv: np.ndarray | None = None      # V^-1 of coupled modes; None: symmetric (V^-1 = V^T)
    coupling_u: np.ndarray | None = None  # the coupling column u [W/K] (coupled modes only)

    @property
    def coupled(self) -> bool:
        """True when the modes include the coupling asked for (see :func:`decompose`)."""
        return self.V_inv is not None

    def to_modes(self, x):
        """Modal coordinates of x (scaled by C^1/2): V^T x for the symmetric modes, V^-1 x for the coupled ones."""
        return self.V_inv @ x if self.V_inv is not None else self.V.T @ x

    def steady(self, b_free):
        """T_inf over the free nodes: K_ff^-1 b_f = C^-1/2 V lambda^-1 V^-1 C^-1/2 b_f."""
        s = self.sqrt_C
        return _re(self.V @ (self.to_modes(b_free / s) / self.lam_per_s)) / s

    def propagate(self, T0_free, Tinf_free, t_s):
        """Free-node temperatures after t_s seconds of held inputs."""
        s = self.sqrt_C
        c = self.to_modes(s * (T0_free - Tinf_free))
        return Tinf_free + _re(self.V @ (c * np.exp(-self.lam_per_s * t_s))) / s

    def time_to_limit(self, T0_free, Tinf_free, rows, limit_c):
        """First time [s] each free node ``rows`` reaches ``limit_c`` (0 if already there, inf if never within the
        horizon), for held inputs: the grid bracket, then :func:`_refine_crossings`."""
        lam, s = self.lam_per_s, self.sqrt_C
        c = self.to_modes(s * (T0_free - Tinf_free))
        W = self.V[rows] / s[rows, None]                  # (r, m)
        Wc = W * c                                        # modal contributions
        T0 = T0_free[rows]
        out = np.full(len(rows), np.inf)
        out[T0 >= limit_c] = 0.0
        # bound: T(t) <= T_inf + sum |W c| for all t >= 0
        reach = (T0 < limit_c) & (Tinf_free[rows] + np.abs(Wc).sum(axis=1) >= limit_c)
        idx = np.flatnonzero(reach)
        if idx.size == 0:
            return out
        F = Tinf_free[rows[idx], None] + _re(Wc[idx] @ self.decay_grid)   # (k, g)
        above = F >= limit_c[idx, None]
        first = np.where(above.any(axis=1), above.argmax(axis=1), -1)
        sel = first > 0
        if sel.any():
            j = idx[sel]
            g = first[sel]
            out[j] = _refine_crossings(Wc[j], lam, Tinf_free[rows[j]] - limit_c[j], g, F[sel, g - 1] - limit_c[j],
                                       F[sel, g] - limit_c[j])
        return out


def _refine_crossings(Wc, lam, f0, g, f_lo, f_hi):
    """The first multiple of TTL_QUANTUM_S at or after each crossing inside the grid bracket
    ``TTL_GRID_S[g - 1] .. TTL_GRID_S[g]`` (f_lo < 0 <= f_hi: T - limit there; f0 = T_inf - limit): regula falsi to
    start, then safeguarded Newton on multiples of the quantum, bisection whenever Newton leaves the bracket."""
    lo, hi = TTL_GRID_S[g - 1], TTL_GRID_S[g]
    wcl = np.stack([Wc, Wc * lam], axis=1)            # (k, 2, m): T(t) - T_inf and -dT/dt from e
    q = TTL_QUANTUM_S
    t = np.round((lo + (hi - lo) * (-f_lo / (f_hi - f_lo))) / q) * q   # regula falsi start in the bracket
    inside = (t > lo) & (t < hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(NEWTON_STEPS):                  # safeguarded Newton on multiples of q (all at once)
            sums = _re((wcl * np.exp(np.multiply.outer(t, -lam))[:, None, :]).sum(axis=2))
            f = f0 + sums[:, 0]
            up = f >= 0.0
            hi = np.where(inside & up, t, hi)
            lo = np.where(inside & ~up, t, lo)
            t_new = np.round((t + f / sums[:, 1]) / q) * q  # t - f / (dT/dt)
            # Newton settled on t: test its neighbour on the open side of the crossing
            t = np.where(t_new == t, np.where(up, t - q, t + q), t_new)
            inside = (t > lo) & (t < hi)
            if not inside.all():                       # else bisect the bracket
                t = np.where(inside, t, np.round(0.5 * (lo + hi) / q) * q)
                inside = (t > lo) & (t < hi)           # False once the bracket is one quantum wide
                if not inside.any():
                    break
    return hi


def decompose(K: np.ndarray, free: np.ndarray, sqrt_C: np.ndarray, coupling: Coupling | None = None) -> HeldModes:
    """Eigen-decomposition of C^-1/2 K C^-1/2 over the free nodes (``sqrt_C``: C^1/2 of every node).

    ``coupling`` (u, j): the system is ``C dT/dt = -(K - u e_j^T) T + b``, a node j (the modelled sump) that
    drives the others through the column u (the oil-system inlet follows the sump through the cooler). That matrix
    is not symmetric: its modes come from a general eigen-decomposition, ``V^-1`` is kept with them, and the record
    says ``coupled`` (and keeps u). Its modes may include a complex pair: the temperatures are then the real parts of
    the modal sums. When an eigenvalue has no positive real part or the eigenvectors are ill-conditioned (V^-1 does
    not reproduce the matrix to 1e-9), the coupling is dropped (the symmetric modes of K) and the record says so
    (``coupled`` False), so that the caller can freeze the inlet instead."""
    s = sqrt_C[free]
    Kf = K[np.ix_(free, free)]
    M = Kf / s[:, None] / s[None, :]
    if coupling is not None:
        modes = _coupled_modes(M, s, free, coupling)
        if modes is not None:
            return modes
    lam, V = np.linalg.eigh(0.5 * (M + M.T))
    lam = np.maximum(lam, 1e-12)
    return _read_only(HeldModes(lam, V, s, free, np.exp(-np.outer(lam, TTL_GRID_S))))


def _coupled_modes(M, s, free, coupling: Coupling) -> HeldModes | None:
    """The general eigen-decomposition of the coupled system (see :func:`decompose`); None when unusable."""
    u = coupling.u_w_per_k
    jf = int(np.searchsorted(free, coupling.node))
    Mc = M.copy()
    Mc[:, jf] -= np.asarray(u, dtype=float)[free] / (s * s[jf])
    try:
        lam, V = np.linalg.eig(Mc)
    except (np.linalg.LinAlgError, ValueError):      # no convergence (or not finite): symmetric modes
        return None
    if np.all(lam.imag == 0.0):
        lam, V = lam.real.copy(), np.ascontiguousarray(V.real)
    # a complex pair (the sump-stream loop can make one) is kept: temperatures are the real parts
    if not np.all(lam.real > 0.0):
        return None
    try:
        V_inv = np.linalg.inv(V)
    except np.linalg.LinAlgError:
        return None
    if not np.abs((V * lam) @ V_inv - Mc).max() <= 1e-9 * np.abs(Mc).max():
        return None
    return _read_only(HeldModes(lam, V, s, free, np.exp(-np.outer(lam, TTL_GRID_S)), V_inv, np.array(u, dtype=float)))


def _read_only(modes: HeldModes) -> HeldModes:
    """The record with its arrays read-only (it is cached and shared)."""
    for a in (modes.lam_per_s, modes.V, modes.sqrt_C, modes.free, modes.decay_grid, modes.V_inv, modes.coupling_u):
        if a is not None:
            a.setflags(write=False)
    return modes


class ModeCache:
    """Held-input modes per quantised operating point: a bounded LRU (a memo of :func:`decompose`, a pure function
    of its key), with hit and miss counts."""

    def __init__(self, size: int = MODE_CACHE_SIZE):
        self.size = size
        self.items: OrderedDict = OrderedDict()
        self.hits = 0
        self.misses = 0

    def get(self, key) -> HeldModes | None:
        """The modes stored under ``key`` (counted as a hit and made the most recent), or None."""
        modes = self.items.get(key)
        if modes is not None:
            self.items.move_to_end(key)
            self.hits += 1
        return modes

    def put(self, key, modes: HeldModes) -> HeldModes:
        """Store ``modes`` under ``key`` (counted as a miss; the least recent item goes when full)."""
        self.misses += 1
        self.items[key] = modes
        if len(self.items) > self.size:
            self.items.popitem(last=False)
        return modes
