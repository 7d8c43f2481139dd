"""The symbolic part of a sparse LDL^T of the onboard network's ``C/h + K`` (the time to limit's march in the C
kernel; firmware_model.onboard.held_march): a fill-reducing elimination order, the pattern of L and the list of
updates, generated once from the topology and handed to the kernel as tables, so that the numeric factorisation an
ECU runs is three flat loops with no search and no allocation.

Order: minimum degree (ties by node index), the sump last. The sump joins most nodes (42 of 60 on GRS905): eliminated
early it would fill the whole matrix; last, L has 178 entries below the diagonal instead of 1830 dense, and a
factorisation costs about 600 multiply-adds. Holding the sump (a measured oil temperature) then only zeroes its row.

Slots: the kernel keeps the matrix in one array ``S``: slot p < n is the diagonal of elimination position p, slot
n + e the e-th entry of L (column-major by position: ``col_ptr[k] .. col_ptr[k + 1]`` are column k's entries, rows
``row[e] > k``). ``link_slot[l]`` is where link l's off-diagonal entry goes (-1 for a boundary link). Factorising
column k: for every update u in ``upd_ptr[k] .. upd_ptr[k + 1]``: ``S[target[u]] -= S[a[u]] * S[b[u]] / S[k]``
(both a and b entries of column k), then column k's entries are divided by ``S[k]``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class LdlPattern(NamedTuple):
    perm: np.ndarray  # (n,) node at each elimination position
    pos: np.ndarray  # (n,) elimination position of each node
    col_ptr: np.ndarray  # (n + 1,)
    row: np.ndarray  # (nnz,) positions
    link_slot: np.ndarray  # (nl,) slot of each internal link's entry, -1 for boundary links
    upd_ptr: np.ndarray  # (n + 1,)
    upd_target: np.ndarray  # slots
    upd_a: np.ndarray
    upd_b: np.ndarray


def ldl_pattern(link_a, link_b, n: int, last: int) -> LdlPattern:
    """The elimination order, the pattern of L and the update list of a network's Laplacian-like matrix (links
    ``link_a``-``link_b``, ``link_b >= n`` a boundary), node ``last`` eliminated last."""
    adj = [set() for _ in range(n)]
    for a, b in zip(np.asarray(link_a).tolist(), np.asarray(link_b).tolist()):
        if b < n and a != b:
            adj[a].add(b)
            adj[b].add(a)
    # minimum degree on the elimination graph, ties by index, `last` last
    graph = [set(s) for s in adj]
    alive = set(range(n))
    perm = []
    while alive:
        cand = [v for v in alive if v != last] or [last]
        v = min(cand, key=lambda x: (len(graph[x] & alive), x))
        nb = graph[v] & alive
        for w in nb:
            graph[w] |= nb - {w}
        alive.remove(v)
        perm.append(v)
    pos = np.empty(n, dtype=np.int64)
    pos[perm] = np.arange(n)
    # the pattern of L: symbolic elimination in position space
    cols = [set() for _ in range(n)]
    for v in range(n):
        for w in adj[v]:
            i, j = pos[v], pos[w]
            if i > j:
                cols[j].add(int(i))
    for k in range(n):
        rows = sorted(cols[k])
        if rows:
            parent = rows[0]  # the elimination tree: column k's fill lands in its first row's column
            cols[parent] |= set(rows[1:])
    col_rows = [sorted(c) for c in cols]
    col_ptr = np.zeros(n + 1, dtype=np.int64)
    col_ptr[1:] = np.cumsum([len(c) for c in col_rows])
    row = np.array([r for c in col_rows for r in c], dtype=np.int64)
    slot = {}
    for k in range(n):
        for e in range(col_ptr[k], col_ptr[k + 1]):
            slot[(int(row[e]), k)] = n + e
    link_slot = np.full(len(link_a), -1, dtype=np.int64)
    for li, (a, b) in enumerate(zip(np.asarray(link_a).tolist(), np.asarray(link_b).tolist())):
        if b < n and a != b:
            i, j = pos[a], pos[b]
            link_slot[li] = slot[(int(max(i, j)), int(min(i, j)))]
    upd_ptr, tgt, ua, ub = [0], [], [], []
    for k in range(n):
        ents = list(range(col_ptr[k], col_ptr[k + 1]))
        for x in range(len(ents)):
            for y in range(x + 1):
                i, j = int(row[ents[x]]), int(row[ents[y]])
                tgt.append(i if i == j else slot[(i, j)])
                ua.append(n + ents[x])
                ub.append(n + ents[y])
        upd_ptr.append(len(tgt))
    i64 = lambda v: np.asarray(v, dtype=np.int64)  # noqa: E731
    return LdlPattern(i64(perm), pos, col_ptr, row, link_slot, i64(upd_ptr), i64(tgt), i64(ua), i64(ub))
