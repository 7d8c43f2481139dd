"""A bounded Gauss-Newton fit for models whose every evaluation replays months of SCADA: the sensitivities are
computed once (one replay per parameter, finite differences), then each step solves the linear least-squares problem
within the bounds and is taken only if a replay confirms the residual fell (else halved, then given up).

scipy's least_squares re-evaluates the Jacobian by finite differences at every iteration (n + 1 replays each); a
thermal model's residual is close to linear in its scales and offsets over their plausible ranges, so one Jacobian
serves, and a fit costs n + 1 + STEPS replays (tools/scada/physics.py, tools/scada/calibrate.py).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Gauss-Newton steps (each one replay, a halving one more)
STEPS = 2


def fit(
    residual: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    step: np.ndarray,
    r0: np.ndarray | None = None,
    jac: np.ndarray | None = None,
) -> dict:
    """Minimise |residual(x)|^2 within [lo, hi] from ``x0``. ``step``: the finite-difference step per parameter
    (taken towards the inside of the bounds); ``r0``/``jac``: the residual at ``x0`` and the sensitivities (columns:
    d residual / d x) when the caller has them. Returns x, the residual there, the Jacobian and the replays made."""
    x = np.asarray(x0, dtype=float).copy()
    n_eval = 0
    if r0 is None:
        r0, n_eval = residual(x), n_eval + 1
    if jac is None:
        cols = []
        for i in range(x.size):
            h = step[i] if x[i] + step[i] <= hi[i] else -step[i]
            xi = x.copy()
            xi[i] += h
            cols.append((residual(xi) - r0) / h)
            n_eval += 1
        jac = np.stack(cols, axis=1)
    r = r0
    for _ in range(STEPS):
        d = bounded_step(jac, r, x, lo, hi)
        for _ in range(2):  # the step, then half of it
            x1 = np.clip(x + d, lo, hi)
            r1 = residual(x1)
            n_eval += 1
            if float(r1 @ r1) < float(r @ r):
                x, r = x1, r1
                break
            d = 0.5 * d
        else:
            break
    return {"x": x, "r": r, "jac": jac, "evaluations": n_eval}


def bounded_step(jac: np.ndarray, r: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The linearised least-squares step d (minimising |r + jac d|) with x + d within [lo, hi]: a parameter whose
    unconstrained step would leave its range is held at the bound it would cross and the others solved again with it
    there (an active set, at most one pass per parameter). Clipping the unconstrained step instead moves the others
    as if the held one had gone all the way: with one parameter at its bound that step is often worse than none."""
    n = x.size
    held = np.zeros(n, dtype=bool)
    d = np.zeros(n)
    for _ in range(n):
        free = ~held
        d_free, *_ = np.linalg.lstsq(jac[:, free], -r - jac[:, held] @ d[held], rcond=None)
        d[free] = d_free
        out = free & ((x + d < lo) | (x + d > hi))
        if not out.any():
            break
        d[out] = np.where(x[out] + d[out] < lo[out], lo[out] - x[out], hi[out] - x[out])
        held |= out
    return d
