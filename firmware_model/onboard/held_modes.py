"""Modal solution of the onboard network with its inputs held: the propagation over a forward time jump (held
inputs) and the cool-down of a snapshot on restart (engine off) (firmware_model.onboard.held_inputs).

With the inputs frozen the onboard network is linear, ``C dT/dt = -K T + b``. ``K`` is symmetric (a weighted
Laplacian plus boundary and cooler terms on its diagonal), so ``C^-1/2 K C^-1/2 = V diag(lambda) V^T`` with real
``lambda > 0`` and ``T(t) = T_inf + C^-1/2 V exp(-lambda t) V^T C^1/2 (T(0) - T_inf)`` exactly. A coupling column
``u`` (``K - u e_node^T``, not symmetric: a node that drives others) gives ``V diag(lambda) V^-1`` from a general
eigen-decomposition, possibly with a complex pair (temperatures are the real parts). :func:`decompose` returns a
:class:`HeldModes` record; it depends only on the operating point, so callers keep it in a :class:`ModeCache` (a
bounded LRU owned by the sensor's step cache) per quantised operating point; ``T_inf`` and the modal coefficients are
recomputed from the current temperatures and heat every time. The time to limit does not use these modes: it marches
the held-input system (firmware_model.onboard.held_march), which an ECU can do without an eigen-solver.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

#: held-input decompositions a ModeCache keeps
MODE_CACHE_SIZE = 64


class Coupling(NamedTuple):
    """A node that drives others through a column: ``C dT/dt = -(K - u e_node^T) T + b``."""

    u_w_per_k: np.ndarray  # (n,) the column u [W/K]
    node: int  # the driving node (the modelled sump)


def _re(x):
    """Real part of a modal sum (the modes of a coupled system may include a complex pair); real input as is."""
    return x.real if np.iscomplexobj(x) else x


@dataclass(frozen=True, eq=False)
class HeldModes:
    """Modes of ``C dT/dt = -K T + b`` over the free nodes, in the coordinates ``C^1/2 T``."""

    lam_per_s: np.ndarray  # (m,) eigenvalues [1/s] (a complex pair possible when coupled)
    V: np.ndarray  # (m, m) eigenvectors (columns)
    sqrt_C: np.ndarray  # (m,) C^1/2 of the free nodes [sqrt(J/K)]
    free: np.ndarray  # indices of the free nodes in the network
    V_inv: np.ndarray | None = None  # V^-1 of coupled modes; None: symmetric (V^-1 = V^T)
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
    return _read_only(HeldModes(lam, V, s, free))


def _coupled_modes(M, s, free, coupling: Coupling) -> HeldModes | None:
    """The general eigen-decomposition of the coupled system (see :func:`decompose`); None when unusable."""
    u = coupling.u_w_per_k
    jf = int(np.searchsorted(free, coupling.node))
    Mc = M.copy()
    Mc[:, jf] -= np.asarray(u, dtype=float)[free] / (s * s[jf])
    try:
        lam, V = np.linalg.eig(Mc)
    except (np.linalg.LinAlgError, ValueError):  # no convergence (or not finite): symmetric modes
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
    return _read_only(HeldModes(lam, V, s, free, V_inv, np.array(u, dtype=float)))


def _read_only(modes: HeldModes) -> HeldModes:
    """The record with its arrays read-only (it is cached and shared)."""
    for a in (modes.lam_per_s, modes.V, modes.sqrt_C, modes.free, modes.V_inv, modes.coupling_u):
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
