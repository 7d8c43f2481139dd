"""The conductance matrix of a thermal network: ``C dT/dt = -K T + b`` (seed section 3, the nodes' energy balance).

A network has n nodes and links; a link joins node ``link_a`` to node ``link_b``, or, when ``link_b >= n``, node
``link_a`` to boundary ``link_b - n``. ``K`` is the weighted Laplacian of the node-node links (G on the diagonal of
both ends, -G between them) plus every node-boundary link's G on its node's diagonal; the boundary links' heat
``G T_boundary`` goes into ``b``. The reference plant (full network) and the onboard model (reduced network) assemble
K with :func:`conductance_matrix`; :func:`node_conductance_w_per_k` is its diagonal without building it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class LinkTopology(NamedTuple):
    """Which links join which nodes, split into node-node (internal) and node-boundary (external) links."""

    n: int  # number of nodes
    link_a: np.ndarray  # (nl,) node of every link
    link_b: np.ndarray  # (nl,) other node, or n + boundary index
    internal: np.ndarray  # (nl,) bool: link_b is a node
    int_idx: np.ndarray  # link indices of the internal links
    ext_idx: np.ndarray  # link indices of the external links
    ia: np.ndarray  # internal links: their two nodes
    ib: np.ndarray
    ea: np.ndarray  # external links: their node and boundary index
    eb: np.ndarray
    lap_idx: np.ndarray  # flat (n x n) positions of the internal links' entries: (a, a), (b, b), (a, b), (b, a)


class ConductanceMatrix(NamedTuple):
    K_w_per_k: np.ndarray  # (n, n)
    G_boundary_w_per_k: np.ndarray  # (n_ext,) conductance of every external link (in ext_idx order)


def link_topology(link_a, link_b, n: int) -> LinkTopology:
    """The topology of a network with ``n`` nodes and links (link_a, link_b)."""
    a = np.asarray(link_a, dtype=np.int64)
    b = np.asarray(link_b, dtype=np.int64)
    internal = b < n
    ia, ib = a[internal], b[internal]
    lap_idx = np.concatenate([ia * n + ia, ib * n + ib, ia * n + ib, ib * n + ia])
    return LinkTopology(
        n,
        a,
        b,
        internal,
        np.flatnonzero(internal),
        np.flatnonzero(~internal),
        ia,
        ib,
        a[~internal],
        b[~internal] - n,
        lap_idx,
    )


def internal_laplacian_w_per_k(G_w_per_k: np.ndarray, topo: LinkTopology) -> np.ndarray:
    """The node-node links' part of K (n, n): their weighted Laplacian, summed in link order."""
    n = topo.n
    Gi = G_w_per_k[topo.int_idx]
    return np.bincount(topo.lap_idx, np.concatenate([Gi, Gi, -Gi, -Gi]), minlength=n * n).reshape(n, n)


def conductance_matrix(
    G_w_per_k: np.ndarray, topo: LinkTopology, diag_w_per_k=None, laplacian_w_per_k=None
) -> ConductanceMatrix:
    """K of the link conductances ``G_w_per_k`` (nl,), plus ``diag_w_per_k`` (n,) on the diagonal when given (e.g. the
    a0 C / dt of an implicit step: the plant solves (a0 C / dt + K) T_new = rhs). ``laplacian_w_per_k``: the
    :func:`internal_laplacian_w_per_k` of these G when the caller kept it (copied, not changed).

    Summation order (it decides the last bits, and both callers keep theirs): the node-node links in link order;
    then the boundary links one by one onto the diagonal, or, with ``diag_w_per_k``, their sum per node added to it
    and the total to the diagonal."""
    n = topo.n
    Ge = G_w_per_k[topo.ext_idx]
    K = internal_laplacian_w_per_k(G_w_per_k, topo) if laplacian_w_per_k is None else laplacian_w_per_k.copy()
    if diag_w_per_k is None:
        np.add.at(K, (topo.ea, topo.ea), Ge)
    else:
        K[np.diag_indices(n)] += diag_w_per_k + np.bincount(topo.ea, Ge, minlength=n)
    return ConductanceMatrix(K, Ge)


def node_conductance_w_per_k(G_w_per_k: np.ndarray, topo: LinkTopology) -> np.ndarray:
    """The diagonal of K: the total conductance of the links at every node [W/K] (n,)."""
    G = np.asarray(G_w_per_k, dtype=float)
    inner = topo.internal
    return np.bincount(topo.link_a, G, minlength=topo.n) + np.bincount(topo.link_b[inner], G[inner], minlength=topo.n)


def boundary_heat_w(G_boundary_w_per_k: np.ndarray, topo: LinkTopology, T_boundary_c: np.ndarray) -> np.ndarray:
    """The boundary links' part of b: sum of G T_boundary at every node [W] (n,)."""
    return np.bincount(topo.ea, G_boundary_w_per_k * T_boundary_c[topo.eb], minlength=topo.n)
